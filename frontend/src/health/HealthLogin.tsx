/**
 * The health page's login: who is logged in, or the shared login form (an operator logs in here
 * to set a baseline). The page takes no robot control, so this is the panel's session bar without
 * its control buttons.
 */
import { useState } from "react";
import { LoginForm } from "../components/LoginForm";
import { api } from "../lib/api/api";
import type { User } from "../lib/api/protocol";

export function HealthLogin({ user, onUser }: { readonly user: User | null; readonly onUser: (user: User | null) => void }) {
  const [busy, setBusy] = useState(false);
  if (user === null) return <LoginForm onUser={onUser} />;
  return (
    <div className="session">
      <span className="session__user" data-testid="current-user" data-role={user.role}>
        {user.name} <span className="session__role">({user.role})</span>
      </span>
      <button
        type="button"
        data-testid="logout"
        disabled={busy}
        onClick={() => {
          setBusy(true);
          void api.logout().finally(() => onUser(null));
        }}
      >
        Log out
      </button>
    </div>
  );
}
