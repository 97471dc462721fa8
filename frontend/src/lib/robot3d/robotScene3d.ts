/**
 * Layer: the one module that imports three.js (its own chunk, loaded when a 3D view is shown).
 *
 * Draws an arm as its kinematic skeleton: a link (cylinder) from each frame's origin to the
 * next, each joint as a short drum along its axis (the frame's z), the flange, the path the
 * flange took over the last seconds, a floor grid with the base frame's axes. The robot's z is
 * up (the camera's `up` is set to z, so no axis is swapped). Meshes are created once and moved
 * by their matrices; nothing is allocated per frame. It draws only when asked (`render`): the
 * view calls it when the pose moved or the camera did. Why three.js and not Plotly's 3D traces:
 * docs/architecture.md, "3D view".
 */
import {
  AmbientLight,
  AxesHelper,
  BufferAttribute,
  BufferGeometry,
  Color,
  CylinderGeometry,
  DirectionalLight,
  GridHelper,
  Line,
  LineBasicMaterial,
  Matrix4,
  Mesh,
  MeshStandardMaterial,
  PerspectiveCamera,
  Quaternion,
  Scene,
  SphereGeometry,
  Vector3,
  WebGLRenderer,
} from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import type { Transform } from "./armKinematics";
import { orbitLimits, orbitOf, positionOf, stepOrbit, type CameraAction, type Orbit, type OrbitLimits } from "./orbitCamera";

export interface RobotSceneOptions {
  readonly theme: "light" | "dark";
  /** Rotate (drag), zoom (wheel) and pan; off on the kiosk. */
  readonly interactive: boolean;
  /** Links (joints) of the arm. */
  readonly jointCount: number;
  /** Most points the flange's path may have. */
  readonly trailCapacity: number;
  /** About how far the arm reaches (m): places the camera and the floor. */
  readonly reach_m: number;
}

const Y_AXIS = new Vector3(0, 1, 0);
/** Cylinders are built along y; a joint's drum must lie along its frame's z. */
const Y_TO_Z = new Matrix4().makeRotationX(Math.PI / 2);

export class RobotScene {
  readonly canvas: HTMLCanvasElement;
  private readonly renderer: WebGLRenderer;
  private readonly scene = new Scene();
  private readonly camera: PerspectiveCamera;
  private readonly controls: OrbitControls | null;
  private readonly links: Mesh[] = [];
  private readonly joints: Mesh[] = [];
  private readonly flange: Mesh;
  private readonly trail: Line;
  private readonly trailPositions: BufferAttribute;
  private readonly home: { position: Vector3; target: Vector3 };
  private readonly limits: OrbitLimits;
  private readonly a = new Vector3();
  private readonly b = new Vector3();
  private readonly dir = new Vector3();
  private readonly q = new Quaternion();
  private readonly m = new Matrix4();
  private readonly disposables: { dispose(): void }[] = [];
  renders = 0;

  constructor(container: HTMLElement, options: RobotSceneOptions) {
    // Throws where the browser has no WebGL: the view says so instead of drawing.
    // No multisampling and at most 1.5 device pixels per CSS pixel: a software-rendered WebGL
    // (a kiosk PC without a GPU, a headless browser) keeps up with every frame this way.
    this.renderer = new WebGLRenderer({ antialias: false, powerPreference: "low-power" });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 1.5));
    this.canvas = this.renderer.domElement;
    container.appendChild(this.canvas);
    const dark = options.theme === "dark";
    this.scene.background = new Color(dark ? "#12161b" : "#ffffff");
    const reach = options.reach_m;

    this.camera = new PerspectiveCamera(40, 1, reach / 100, reach * 50);
    this.camera.up.set(0, 0, 1);
    this.home = {
      position: new Vector3(1.05 * reach, -0.85 * reach, 0.7 * reach),
      target: new Vector3(0, 0, 0.3 * reach),
    };

    this.scene.add(new AmbientLight(0xffffff, dark ? 1.2 : 1.6));
    const sun = new DirectionalLight(0xffffff, 2.2);
    sun.position.set(2 * reach, -1 * reach, 4 * reach);
    this.scene.add(sun);

    const grid = new GridHelper(3 * reach, 12, dark ? 0x4a5563 : 0xb0b8c0, dark ? 0x2a3139 : 0xe1e5e9);
    grid.rotation.x = Math.PI / 2; // GridHelper lies in x-z; the floor here is x-y
    this.scene.add(grid);
    const axes = new AxesHelper(0.25 * reach);
    this.scene.add(axes);
    this.disposables.push(grid, axes);

    const linkGeometry = new CylinderGeometry(1, 1, 1, 20); // scaled per link
    const jointGeometry = new CylinderGeometry(1, 1, 1, 24);
    const ball = new SphereGeometry(1, 20, 14);
    const linkMaterial = new MeshStandardMaterial({ color: dark ? "#c9d1d9" : "#d7dce1", metalness: 0.1, roughness: 0.6 });
    const jointMaterial = new MeshStandardMaterial({ color: "#0072B2", metalness: 0.2, roughness: 0.5 });
    const flangeMaterial = new MeshStandardMaterial({ color: "#E69F00", roughness: 0.5 });
    this.disposables.push(linkGeometry, jointGeometry, ball, linkMaterial, jointMaterial, flangeMaterial);
    const r = reach * 0.045;
    for (let i = 0; i < options.jointCount; i++) {
      const link = new Mesh(linkGeometry, linkMaterial);
      link.scale.set(r, 1, r);
      this.links.push(link);
      this.scene.add(link);
      const joint = new Mesh(jointGeometry, jointMaterial);
      joint.matrixAutoUpdate = false;
      this.joints.push(joint);
      this.scene.add(joint);
    }
    // The base: a pedestal under J1.
    const base = new Mesh(jointGeometry, linkMaterial);
    base.scale.set(r * 2, reach * 0.02, r * 2);
    base.rotation.x = Math.PI / 2;
    base.position.set(0, 0, reach * 0.01);
    this.scene.add(base);
    this.flange = new Mesh(ball, flangeMaterial);
    this.flange.scale.setScalar(r * 0.9);
    this.scene.add(this.flange);

    const trailGeometry = new BufferGeometry();
    this.trailPositions = new BufferAttribute(new Float32Array(options.trailCapacity * 3), 3);
    trailGeometry.setAttribute("position", this.trailPositions);
    trailGeometry.setDrawRange(0, 0);
    const trailMaterial = new LineBasicMaterial({ color: dark ? "#F0E442" : "#D55E00" });
    this.trail = new Line(trailGeometry, trailMaterial);
    this.trail.frustumCulled = false; // its bounds change every frame
    this.scene.add(this.trail);
    this.disposables.push(trailGeometry, trailMaterial);

    this.jointRadius = r * 1.25;
    this.jointLength = r * 2.6;

    this.limits = orbitLimits(reach);
    if (options.interactive) {
      this.controls = new OrbitControls(this.camera, this.canvas);
      this.controls.enableDamping = false; // a change redraws once, not for a second afterwards
      // The mouse keeps within the limits the buttons and keys do (polar angle: from +z, the up).
      this.controls.minDistance = this.limits.minDistance_m;
      this.controls.maxDistance = this.limits.maxDistance_m;
      this.controls.minPolarAngle = Math.PI / 2 - this.limits.maxElevation_rad;
      this.controls.maxPolarAngle = Math.PI / 2 - this.limits.minElevation_rad;
    } else {
      this.controls = null;
    }
    this.resetView();
  }

  private readonly jointRadius: number;
  private readonly jointLength: number;

  /** The flange's path, `count` points of x, y, z (m) from `xyz`. */
  get trailArray(): Float32Array {
    return this.trailPositions.array as Float32Array;
  }

  /** Called by the controls when the person rotates, zooms or pans. */
  onCameraChange(listener: () => void): void {
    this.controls?.addEventListener("change", listener);
  }

  resetView(): void {
    this.camera.position.copy(this.home.position);
    if (this.controls !== null) {
      this.controls.target.copy(this.home.target);
      this.controls.update();
    } else {
      this.camera.lookAt(this.home.target);
    }
  }

  /** Where the camera is, around the point it looks at (m, rad; base frame, z up). */
  orbit(): Orbit {
    return orbitOf(this.camera.position, this.controls?.target ?? this.home.target);
  }

  /** One press of a view button or key: turn, zoom or reset, within the mouse's limits. */
  cameraAction(action: CameraAction): void {
    if (action === "reset") {
      this.resetView();
      return;
    }
    const target = this.controls?.target ?? this.home.target;
    positionOf(stepOrbit(this.orbit(), action, this.limits), target, this.camera.position);
    if (this.controls !== null) this.controls.update();
    else this.camera.lookAt(target);
  }

  resize(width_px: number, height_px: number): void {
    if (width_px <= 0 || height_px <= 0) return;
    this.renderer.setSize(width_px, height_px, false);
    this.camera.aspect = width_px / height_px;
    this.camera.updateProjectionMatrix();
  }

  /** Place every link and joint from the frames (base first, flange last; m, base frame). */
  setPose(frames: readonly Transform[]): void {
    for (let i = 0; i < this.links.length; i++) {
      const from = frames[i];
      const to = frames[i + 1];
      const link = this.links[i] as Mesh;
      const joint = this.joints[i] as Mesh;
      if (from === undefined || to === undefined) continue;
      this.a.set(from[3] as number, from[7] as number, from[11] as number);
      this.b.set(to[3] as number, to[7] as number, to[11] as number);
      this.dir.subVectors(this.b, this.a);
      const length = this.dir.length();
      link.visible = length > 1e-6; // J4 and J5 share an origin: no link between them
      if (link.visible) {
        link.position.addVectors(this.a, this.b).multiplyScalar(0.5);
        link.quaternion.copy(this.q.setFromUnitVectors(Y_AXIS, this.dir.divideScalar(length)));
        link.scale.y = length;
      }
      // The joint's drum: along z of the frame it turns (the child link's frame).
      const t = to;
      this.m.set(
        t[0] as number, t[1] as number, t[2] as number, t[3] as number,
        t[4] as number, t[5] as number, t[6] as number, t[7] as number,
        t[8] as number, t[9] as number, t[10] as number, t[11] as number,
        0, 0, 0, 1,
      );
      joint.matrix.copy(this.m).multiply(Y_TO_Z).scale(this.b.set(this.jointRadius, this.jointLength, this.jointRadius));
      joint.matrixWorldNeedsUpdate = true;
    }
    const last = frames[frames.length - 1];
    if (last !== undefined) this.flange.position.set(last[3] as number, last[7] as number, last[11] as number);
  }

  /** Show the first `count` points written into `trailArray`. */
  setTrailCount(count: number): void {
    this.trailPositions.needsUpdate = true;
    this.trail.geometry.setDrawRange(0, count);
  }

  render(): void {
    this.renderer.render(this.scene, this.camera);
    this.renders++;
  }

  dispose(): void {
    this.controls?.dispose();
    for (const d of this.disposables) d.dispose();
    this.renderer.dispose();
    this.canvas.remove();
  }
}
