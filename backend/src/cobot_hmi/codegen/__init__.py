"""Layer: layout tooling. Imports ``cobot_hmi.layout``, ``cobot_hmi.arms`` and, for the golden
vectors only, the emulator's pure robot model (``emulator.robot.models`` and ``.kinematics``).

Writes every file that derives from the layout table, so that nothing else repeats an offset, a
name or a state value:

- ``backend/src/cobot_hmi/generated/frames.py`` (``python_frames``): the typed ``Frame`` and
  ``CommandImage`` classes, the ``RobotState`` enum, and the decode / encode functions with
  their ``struct`` formats compiled once (the backend's hot path: one ``unpack_from`` and table
  look-ups per frame);
- ``backend/src/cobot_hmi/generated/layout.json`` (``layout_json``): the layout the backend serves;
- ``frontend/src/generated/layout.ts`` (``typescript``): types and constants for the frontend;
- ``frontend/src/generated/arms.ts`` (``arms_ts``): the arms' joint chains (``cobot_hmi.arms``) for
  the panel's 3D view;
- ``frontend/src/generated/armKinematicsVectors.json`` (``arm_vectors``): golden forward-kinematics
  vectors of every arm computed by the emulator's model, which pytest and Vitest check the Python
  and the TypeScript kinematics against;
- ``docs/assembly.md`` (``markdown``): the map a human reads;
- ``backend/src/cobot_hmi/generated/sparkplug_b_pb2.py`` and ``.pyi`` (``sparkplug_proto``): the
  Sparkplug B payload classes, compiled from ``sparkplug/sparkplug_b.proto`` by grpcio-tools.

Run ``cobot-hmi codegen`` (or ``python -m cobot_hmi.codegen``) after changing the layout;
``--check`` exits non-zero when a committed file is stale (the test suite runs it).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cobot_hmi.codegen.arm_vectors import arm_vectors_json
from cobot_hmi.codegen.arms_ts import arms_ts
from cobot_hmi.codegen.layout_json import layout_document, layout_json
from cobot_hmi.codegen.markdown import assembly_doc
from cobot_hmi.codegen.python_frames import frames_module
from cobot_hmi.codegen.sparkplug_proto import sparkplug_modules
from cobot_hmi.codegen.typescript import layout_ts

__all__ = ["ARM_VECTORS_FILE", "layout_document", "main", "outputs", "stale_outputs"]

PACKAGE_DIR = Path(__file__).resolve().parents[1]
REPO_ROOT = Path(__file__).resolve().parents[4]
ARM_VECTORS_FILE = REPO_ROOT / "frontend" / "src" / "generated" / "armKinematicsVectors.json"


def outputs() -> dict[Path, str]:
    """Every derived file and its expected content."""
    return {
        PACKAGE_DIR / "generated" / "frames.py": frames_module(),
        PACKAGE_DIR / "generated" / "layout.json": layout_json(),
        REPO_ROOT / "frontend" / "src" / "generated" / "layout.ts": layout_ts(),
        REPO_ROOT / "frontend" / "src" / "generated" / "arms.ts": arms_ts(),
        ARM_VECTORS_FILE: arm_vectors_json(),
        REPO_ROOT / "docs" / "assembly.md": assembly_doc(),
        **{PACKAGE_DIR / "generated" / name: text for name, text in sparkplug_modules().items()},
    }


def stale_outputs() -> list[Path]:
    """Derived files whose committed content differs from what the layout generates."""
    return [
        path
        for path, text in outputs().items()
        if not path.exists() or path.read_text(encoding="utf-8") != text
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="cobot-hmi codegen", description=__doc__.split("\n")[2])
    parser.add_argument("--check", action="store_true", help="exit 1 if a derived file is stale")
    args = parser.parse_args(argv)
    if args.check:
        stale = stale_outputs()
        for path in stale:
            print(f"stale: {path.relative_to(REPO_ROOT)} (run `cobot-hmi codegen`)")
        return 1 if stale else 0
    for path, text in outputs().items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path.relative_to(REPO_ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
