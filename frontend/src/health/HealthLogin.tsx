/**
 * The health page's login: who is logged in, or a small form (an operator logs in here to set a
 * baseline). The page takes no robot control, so this is the panel's login without its control
 * buttons.
 */
import { useState, type FormEvent } from "react";
import { api, errorReason } from "../lib/api/api";
import { userOf, type User } from "../lib/api/protocol";

export function HealthLogin({ user, onUser }: { readonly user: User | null; readonly onUser: (user: User | null) => void }) {
  const [username, setUsername] = useState("");
  const [password, setPassword] = useState("");
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<string | null>(null);

  if (user !== null) {
    return (
      <div className="session">
        <span className="session__user" data-testid="current-user" data-role={user.role}>
          {user.name} <span className="session__role">({user.role})</span>
        </span>
        <button type="button" data-testid="logout" disabled={busy} onClick={() => void api.logout().finally(() => onUser(null))}>
          Log out
        </button>
      </div>
    );
  }

  const submit = async (e: FormEvent) => {
    e.preventDefault();
    setBusy(true);
    setError(null);
    try {
      const answer = await api.login(username, password);
      if (answer.status === 200) {
        setPassword("");
        onUser(userOf((answer.body as { user?: unknown } | null)?.user));
      } else {
        setError(answer.status === 401 ? "wrong user name or password" : errorReason(answer));
      }
    } catch (err) {
      setError(err instanceof Error ? err.message : String(err));
    } finally {
      setBusy(false);
    }
  };

  return (
    <form className="session session--login" onSubmit={(e) => void submit(e)} aria-label="Operator login">
      <input aria-label="User name" placeholder="user" autoComplete="username" data-testid="login-username" value={username} onChange={(e) => setUsername(e.target.value)} />
      <input
        aria-label="Password"
        placeholder="password"
        type="password"
        autoComplete="current-password"
        data-testid="login-password"
        value={password}
        onChange={(e) => setPassword(e.target.value)}
      />
      <button type="submit" data-testid="login-submit" disabled={busy || username === ""}>
        Log in
      </button>
      {error !== null && (
        <span className="reason" data-testid="login-error" role="alert">
          {error}
        </span>
      )}
    </form>
  );
}
