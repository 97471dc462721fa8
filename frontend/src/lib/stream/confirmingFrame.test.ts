// Issue 38 item 13: after "confirmed" the page shows the frame that confirmed the write at once,
// not at the next periodic publish (up to 250 ms later): `LiveData.showFrame`, called with the
// write's answer's `seq` (panel/writeContext.tsx, panel/PresetsView.tsx).
import { describe, expect, it } from "vitest";
import type { Frame } from "../../generated/layout";
import { LiveData } from "./liveData";
import { JOINT_PLOTS } from "../plots/plots";

function frame(ao: number): Frame {
  return { robot_state: 14, emergency_stopped: false, analog_output: [ao, 0], analog_output_type: [1, 0] } as unknown as Frame;
}

function setup() {
  const clock = { t: 1000 };
  const live = new LiveData(JOINT_PLOTS, { capacity: 16, now: () => clock.t, publishInterval_ms: 250 });
  let published = 0;
  live.subscribe(() => published++);
  live.handle({ type: "frames", frames: [{ seq: 1, t: 1, frame: frame(0) }] }); // the first: published
  return { live, clock, published: () => published, shownAo: () => live.getSnapshot().frame?.analog_output[0] };
}

describe("the confirming frame", () => {
  it("is shown the moment it arrives after the answer named it", () => {
    const { live, published, shownAo } = setup();
    const before = published();
    live.showFrame(3); // the PATCH answer came first (the stream lags it)
    live.handle({ type: "frames", frames: [{ seq: 2, t: 1.01, frame: frame(0) }] });
    expect(published()).toBe(before); // not that one yet
    live.handle({ type: "frames", frames: [{ seq: 3, t: 1.02, frame: frame(5) }] });
    expect(published()).toBe(before + 1);
    expect(shownAo()).toBe(5);
    live.handle({ type: "frames", frames: [{ seq: 4, t: 1.03, frame: frame(5) }] });
    expect(published()).toBe(before + 1); // then the periodic publishes again
  });

  it("is shown at once when it arrived before the answer", () => {
    const { live, published, shownAo } = setup();
    live.handle({ type: "frames", frames: [{ seq: 2, t: 1.01, frame: frame(7) }] });
    expect(shownAo()).toBe(0); // waits for the periodic publish …
    const before = published();
    live.showFrame(2); // … unless a write's answer names it
    expect(published()).toBe(before + 1);
    expect(shownAo()).toBe(7);
  });
});
