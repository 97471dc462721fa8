/**
 * The login form the pages share (the panel's session bar, the health page): user name and
 * password, the service's reason when it refuses. It asks the service's login and hands the user
 * it answers to `onUser`; what a page does with a session (control, its idle clock) stays the page's.
 */
import { useState, type FormEvent } from "react";
import { api, errorReason } from "../lib/api/api";
import { userOf, type User } from "../lib/api/protocol";

export function LoginForm({ onUser }: { readonly onUser: (user: User | null) => void }) {
  const [username, setUsername] = useState("");
  const [password, setPassword] = useState("");
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<string | null>(null);

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
