/**
 * The login form (components/LoginForm), the logged-in user, and Take control / Release of the robot shown. While logged in
 * it keeps the session's idle clock (useSessionIdle): an expired session turns the page to
 * logged out at once, with "Session expired: log in again" (the service has released control).
 */
import { useCallback, useState } from "react";
import { LoginForm } from "../components/LoginForm";
import { api, controlOf, errorReason } from "../lib/api/api";
import { SESSION_EXPIRED_WORDS } from "../lib/writes/sessionIdle";
import { useSessionIdle } from "./useSessionIdle";
import type { Ownership } from "../lib/writes/controlSession";
import { roleAtLeast, type ControlStatus, type User } from "../lib/api/protocol";
import type { HttpAnswer } from "../lib/writes/writes";

interface Props {
  /** The robot whose control the buttons take and release. */
  readonly robot: string;
  readonly user: User | null;
  /** Whose control it is as this window sees it (a session's, not a user name's). */
  readonly ownership: Ownership;
  readonly onUser: (user: User | null) => void;
  readonly onControl: (control: ControlStatus) => void;
  /**
   * A phone's compact header shows a "Log in" button rather than the form (styles/responsive.css):
   * it opens the header's menu, where the form is.
   */
  readonly onLoginWanted?: () => void;
  /** Right before the logout is asked for: the service will close this session's streams. */
  readonly onLoggingOut?: () => void;
}

export function SessionBar({ robot, user, ownership, onUser, onControl, onLoginWanted, onLoggingOut }: Props) {
  const [busy, setBusy] = useState(false);
  const [controlError, setControlError] = useState<string | null>(null);
  const [expired, setExpired] = useState(false);
  const onExpired = useCallback(() => {
    setExpired(true);
    onUser(null);
  }, [onUser]);
  useSessionIdle(user, onExpired);

  const controlAction = async (action: () => Promise<HttpAnswer>) => {
    setBusy(true);
    setControlError(null);
    try {
      const answer = await action();
      const status = controlOf(answer);
      if (status !== null) onControl(status);
      else setControlError(errorReason(answer));
    } catch (error) {
      setControlError(error instanceof Error ? error.message : String(error));
    } finally {
      setBusy(false);
    }
  };

  if (user === null) {
    return (
      <>
        {expired && (
          <span className="session__expired reason" data-testid="session-expired" role="alert">
            {SESSION_EXPIRED_WORDS}
          </span>
        )}
        {onLoginWanted !== undefined && (
          <button
            type="button"
            className="session__login-open"
            data-testid="login-open"
            onClick={() => {
              onLoginWanted();
              // The form shows with the menu, in the next frame: the cursor goes into its first field.
              requestAnimationFrame(() => document.querySelector<HTMLInputElement>('[data-testid="login-username"]')?.focus());
            }}
          >
            Log in
          </button>
        )}
        <LoginForm
          onUser={(next) => {
            setExpired(false);
            onUser(next);
          }}
        />
      </>
    );
  }

  // Control belongs to a session: the same user's other window holds it, not this one.
  const holding = ownership === "you";
  const operator = roleAtLeast(user, "operator");
  return (
    <div className="session">
      <span className="session__user" data-testid="current-user" data-role={user.role}>
        {user.name} <span className="session__role">({user.role})</span>
      </span>
      {ownership === "you-elsewhere" && (
        <span className="hint" data-testid="control-held-elsewhere">
          Control is held by you in another window: release it there to take it here.
        </span>
      )}
      {operator && ownership !== "you" && ownership !== "you-elsewhere" && (
        <button type="button" className="primary" data-testid="take-control" disabled={busy} onClick={() => void controlAction(() => api.takeControl(robot))}>
          Take control
        </button>
      )}
      {holding && (
        <button type="button" data-testid="release-control" disabled={busy} onClick={() => void controlAction(() => api.releaseControl(robot))}>
          Release
        </button>
      )}
      <button
        type="button"
        className="session__logout"
        data-testid="logout"
        disabled={busy}
        onClick={() => {
          onLoggingOut?.();
          void api.logout().finally(() => onUser(null));
        }}
      >
        Log out
      </button>
      {controlError !== null && (
        <span className="reason" data-testid="control-error" role="alert">
          {controlError}
        </span>
      )}
    </div>
  );
}
