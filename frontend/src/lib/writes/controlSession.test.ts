import { describe, expect, it } from "vitest";
import { controlOwnership, holderWords } from "./controlSession";
import type { ControlStatus, User } from "../api/protocol";

const alice: User = { name: "alice", role: "operator" };
const bob: User = { name: "bob", role: "operator" };

function held(over: Partial<NonNullable<ControlStatus["holder"]>> = {}): ControlStatus {
  return { holder: { user: "alice", since: 1, session: "s-a", ...over } };
}

describe("whose control it is (a session's, not a user name's)", () => {
  it("nobody", () => {
    expect(controlOwnership({ holder: null }, alice, "s-a")).toBe("nobody");
  });

  it("believes the service's session_is_yours (status, robots, hello, take/release answers)", () => {
    expect(controlOwnership(held({ session_is_yours: true }), alice, null)).toBe("you");
    // The same user in a second window: not this window's control.
    expect(controlOwnership(held({ session_is_yours: false }), alice, "s-b")).toBe("you-elsewhere");
    expect(controlOwnership(held({ session_is_yours: false }), bob, "s-b")).toBe("other");
  });

  it("compares the event's holder session with the window's own (events carry no session_is_yours)", () => {
    expect(controlOwnership(held({ session_is_yours: null }), alice, "s-a")).toBe("you");
    expect(controlOwnership(held({ session_is_yours: null }), alice, "s-b")).toBe("you-elsewhere");
    expect(controlOwnership(held(), bob, "s-b")).toBe("other");
  });

  it("without a session to compare, falls back to the user name; logged out is never yours", () => {
    expect(controlOwnership(held({ session: null }), alice, "s-b")).toBe("you");
    expect(controlOwnership(held(), alice, null)).toBe("you");
    expect(controlOwnership(held({ session_is_yours: true }), null, "s-a")).toBe("other");
  });

  it("says it in words", () => {
    expect(holderWords(held(), "you-elsewhere")).toBe("held by you in another window");
    expect(holderWords(held(), "other")).toBe("alice");
    expect(holderWords({ holder: null }, "nobody")).toBe("nobody");
  });
});
