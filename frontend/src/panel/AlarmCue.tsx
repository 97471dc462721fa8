/**
 * The panel's audible alarm cue and its mute button. It beeps (Web Audio, no sound files) while
 * an alarm that needs a person is unacknowledged — faster and higher for a more urgent priority
 * (lib/alarms/alarms.ts `cueTone`) — until the operator mutes it; an alarm that comes after the mute
 * sounds again. Browsers start sound only after a click on the page: until then the button says
 * that sound is blocked. Muting is this window's own business: nothing is sent to the service.
 */
import { useEffect, useRef, useState } from "react";
import { cueTone, mute, NO_MUTE, sounding, type Alarm, type Mute } from "../lib/alarms/alarms";

const BEEP_S = 0.18;
const BEEP_GAP_S = 0.12;

type AudioCtor = typeof AudioContext;

function audioContextClass(): AudioCtor | null {
  const w = window as unknown as { AudioContext?: AudioCtor; webkitAudioContext?: AudioCtor };
  return w.AudioContext ?? w.webkitAudioContext ?? null;
}

function beep(context: AudioContext, frequency_hz: number, beeps: number): void {
  const start = context.currentTime + 0.02;
  for (let i = 0; i < beeps; i++) {
    const t = start + i * (BEEP_S + BEEP_GAP_S);
    const osc = context.createOscillator();
    const gain = context.createGain();
    osc.type = "square";
    osc.frequency.value = frequency_hz;
    gain.gain.setValueAtTime(0.0001, t);
    gain.gain.exponentialRampToValueAtTime(0.15, t + 0.01);
    gain.gain.exponentialRampToValueAtTime(0.0001, t + BEEP_S);
    osc.connect(gain).connect(context.destination);
    osc.start(t);
    osc.stop(t + BEEP_S + 0.02);
  }
}

export function AlarmCue({ alarms }: { readonly alarms: readonly Alarm[] }) {
  const [muted, setMuted] = useState<Mute>(NO_MUTE);
  const [blocked, setBlocked] = useState(false);
  const context = useRef<AudioContext | null>(null);
  const now = sounding(alarms, muted);
  const top = now[0];
  const priority = top?.priority ?? null;

  // One context per page, resumed on the first click anywhere (browsers' autoplay rule).
  useEffect(() => {
    const resume = () => {
      const ctx = context.current;
      if (ctx !== null && ctx.state === "suspended") void ctx.resume().then(() => setBlocked(false));
    };
    window.addEventListener("pointerdown", resume);
    window.addEventListener("keydown", resume);
    return () => {
      window.removeEventListener("pointerdown", resume);
      window.removeEventListener("keydown", resume);
    };
  }, []);

  useEffect(
    () => () => {
      void context.current?.close();
      context.current = null;
    },
    [],
  );

  useEffect(() => {
    if (priority === null) return;
    const Ctor = audioContextClass();
    if (Ctor === null) return;
    try {
      context.current ??= new Ctor();
    } catch {
      return; // no audio device: the banner still shows everything
    }
    const ctx = context.current;
    const tone = cueTone(priority);
    const play = () => {
      if (ctx.state === "suspended") {
        setBlocked(true);
        void ctx.resume().then(() => setBlocked(false), () => undefined);
        return;
      }
      beep(ctx, tone.frequency_hz, tone.beeps);
    };
    play();
    const timer = setInterval(play, tone.period_ms);
    return () => clearInterval(timer);
  }, [priority]);

  if (now.length === 0 && muted.silenced.size === 0) return null;
  return (
    <button
      type="button"
      className="alarm-cue"
      data-testid="alarm-mute"
      data-sounding={now.length > 0 ? "true" : "false"}
      disabled={now.length === 0}
      title={blocked ? "The browser blocks sound until you click the page" : undefined}
      onClick={() => setMuted(mute(alarms))}
    >
      {now.length > 0 ? (blocked ? "Mute (sound blocked until a click)" : "Mute sound") : "Sound muted"}
    </button>
  );
}
