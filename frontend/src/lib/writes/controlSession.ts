/**
 * Layer: pure rules for whose control it is (no React, no DOM, no network).
 *
 * Control of a robot's outputs belongs to one login session, not to a user name (docs/api.md,
 * "Writing"): the same user logged in in two windows holds control in one of them only, and
 * only that one may write or release. The service says so per request
 * (`Holder.session_is_yours` in a status, a robot list, a take/release answer and the stream's
 * hello); events carry `Holder.session` instead, which the window compares with its stream's own
 * session (`hello.session`).
 */
import type { ControlStatus, User } from "../api/protocol";

/**
 * nobody: no one holds control; you: this window's session; you-elsewhere: the same user in
 * another session ("held by you in another window"); other: someone else.
 */
export type Ownership = "nobody" | "you" | "you-elsewhere" | "other";

export function controlOwnership(control: ControlStatus, user: User | null, session: string | null): Ownership {
  const holder = control.holder;
  if (holder === null) return "nobody";
  if (user === null) return "other";
  const sameUser = holder.user === user.name;
  let mine: boolean;
  if (holder.session_is_yours === true || holder.session_is_yours === false) {
    mine = holder.session_is_yours;
  } else if (holder.session !== null && holder.session !== undefined && session !== null) {
    mine = holder.session === session;
  } else {
    // A service that does not say whose session it is: the user name is all there is.
    mine = sameUser;
  }
  if (mine) return "you";
  return sameUser ? "you-elsewhere" : "other";
}

/** The holder in words for the header: "you", "you in another window", the user, "nobody". */
export function holderWords(control: ControlStatus, ownership: Ownership): string {
  switch (ownership) {
    case "nobody":
      return "nobody";
    case "you":
      return "you";
    case "you-elsewhere":
      return "held by you in another window";
    case "other":
      return control.holder?.user ?? "nobody";
  }
}

