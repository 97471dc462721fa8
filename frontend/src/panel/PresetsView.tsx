/**
 * Output presets of the robot shown (docs/operations.md "Output presets"): named sets of outputs
 * and registers ("Job 3", "All outputs off", which every robot has). Applying one is ONE write
 * through the write pipeline (control needed; all values or none), after a confirmation that
 * lists what changes. An operator saves the command image being sent as a preset (all of it,
 * or the registers only) or values typed by hand ("Register in 0 = on, DO 3 = off"), deletes
 * one, imports the CSV or JSON export.
 */
import { memo, useCallback, useContext, useEffect, useState, type ChangeEvent } from "react";
import { ConfirmDialog } from "../components/ConfirmDialog";
import { RuntimeContext } from "../components/runtimeContext";
import { roleAtLeast, type User } from "../lib/api/protocol";
import { changeLines, parsePresetItems, presetWords, presetsApi, presetsCsvUrl, presetsJsonUrl, type Preset } from "../lib/commissioning/presets";

interface Pending {
  readonly preset: string;
  readonly lines: readonly string[];
}

function confirmWords(pending: Pending): string {
  if (pending.lines.length === 0) return `Apply preset “${pending.preset}”? Nothing changes: every value is already so.`;
  return `Apply preset “${pending.preset}”? This changes ${pending.lines.length} value(s): ${pending.lines.join("; ")}.`;
}

export const PresetsView = memo(function PresetsView({ robot, user }: { readonly robot: string; readonly user: User | null }) {
  const [presets, setPresets] = useState<readonly Preset[]>([]);
  const [name, setName] = useState("");
  const [registersOnly, setRegistersOnly] = useState(true);
  const [values, setValues] = useState("");
  const [pending, setPending] = useState<Pending | null>(null);
  const [note, setNote] = useState<string | null>(null);
  const [error, setError] = useState<string | null>(null);
  const runtime = useContext(RuntimeContext);
  const [busy, setBusy] = useState(false);
  const [reload, setReload] = useState(0);
  const operator = roleAtLeast(user, "operator");

  useEffect(() => {
    let cancelled = false;
    presetsApi
      .list(robot)
      .then((answer) => {
        if (cancelled) return;
        if (answer.ok) setPresets(answer.page.items);
        else setError(answer.reason);
      })
      .catch((e: unknown) => !cancelled && setError(String(e)));
    return () => {
      cancelled = true;
    };
  }, [robot, reload, user]);

  const run = useCallback(async (work: () => Promise<string | null>) => {
    setBusy(true);
    setNote(null);
    try {
      const failed = await work();
      setError(failed);
    } catch (e) {
      setError(String(e));
    } finally {
      setBusy(false);
    }
  }, []);

  const ask = (preset: string) =>
    void run(async () => {
      const answer = await presetsApi.changes(robot, preset);
      if (!answer.ok) return answer.reason;
      setPending({ preset, lines: changeLines(answer.page.changes) });
      return null;
    });

  const answer = (ok: boolean) => {
    const asked = pending;
    setPending(null);
    if (!ok || asked === null) return;
    void run(async () => {
      const applied = await presetsApi.apply(robot, asked.preset);
      if (!applied.ok) return applied.reason;
      // The outputs show the frame that confirmed it the moment it is here (lib/stream/liveData.ts).
      const seq = applied.page.seq;
      if (seq !== null && seq !== undefined) runtime?.live.showFrame(seq);
      setNote(`“${asked.preset}” applied: ${applied.page.changes.length} value(s) changed, confirmed by the robot`);
      return null;
    });
  };

  const save = () =>
    void run(async () => {
      const saved = await presetsApi.saveFromImage(robot, name.trim(), registersOnly ? ["bit_input_registers"] : null);
      if (!saved.ok) return saved.reason;
      setNote(`“${saved.page.name}” saved`);
      setName("");
      setReload((n) => n + 1);
      return null;
    });

  const saveTyped = () =>
    void run(async () => {
      const parsed = parsePresetItems(values);
      if (!parsed.ok) return parsed.reason;
      const saved = await presetsApi.saveItems(robot, name.trim(), parsed.items);
      if (!saved.ok) return saved.reason;
      setNote(`“${saved.page.name}” saved`);
      setName("");
      setValues("");
      setReload((n) => n + 1);
      return null;
    });

  const remove = (preset: string) =>
    void run(async () => {
      const answer = await presetsApi.remove(robot, preset);
      if (!answer.ok) return answer.reason;
      setPresets(answer.page.items);
      return null;
    });

  const importFile = (e: ChangeEvent<HTMLInputElement>) => {
    const file = e.target.files?.[0];
    e.target.value = "";
    if (file === undefined) return;
    void run(async () => {
      const answer = await presetsApi.importText(robot, await file.text(), file.name);
      if (!answer.ok) return answer.reason;
      setPresets(answer.page.items);
      setNote(`imported ${file.name}`);
      return null;
    });
  };

  return (
    <div className="table-view presets" data-testid="presets-view">
      <div className="table-view__bar">
        {operator && (
          <>
            <label>
              name <input data-testid="preset-name" value={name} maxLength={64} placeholder="Job 3" onChange={(e) => setName(e.target.value)} />
            </label>
            <label>
              <input type="checkbox" checked={registersOnly} onChange={(e) => setRegistersOnly(e.target.checked)} /> registers only
            </label>
            <button type="button" data-testid="preset-save" disabled={busy || name.trim() === ""} onClick={save}>
              Save the outputs being sent
            </button>
            <label>
              or values{" "}
              <input data-testid="preset-values" value={values} size={32} placeholder="Register in 0 = on, DO 3 = off, AO 0 = 12" onChange={(e) => setValues(e.target.value)} />
            </label>
            <button type="button" data-testid="preset-save-values" disabled={busy || name.trim() === "" || values.trim() === ""} onClick={saveTyped}>
              Save these values
            </button>
            <label className="tags-view__import">
              Import CSV/JSON <input type="file" accept=".csv,.json,text/csv,application/json" data-testid="preset-import" disabled={busy} onChange={importFile} />
            </label>
          </>
        )}
        <a href={presetsCsvUrl(robot)} download={`${robot}-presets.csv`}>
          Export CSV
        </a>
        <a href={presetsJsonUrl(robot)} download={`${robot}-presets.json`}>
          Export JSON
        </a>
        {note !== null && <span data-testid="preset-note">{note}</span>}
        {error !== null && (
          <span className="reason" role="alert" data-testid="preset-error">
            {error}
          </span>
        )}
      </div>
      <div className="table-scroll" tabIndex={0} role="region" aria-label="Output presets">
        <table data-testid="presets-table">
          <thead>
            <tr>
              <th>preset</th>
              <th>values</th>
              <th>made</th>
              <th className="no-print">actions</th>
            </tr>
          </thead>
          <tbody>
            {presets.map((p) => (
              <tr key={p.name} data-testid="preset-row" data-name={p.name}>
                <td className="nowrap">{p.name}</td>
                <td>{presetWords(p)}</td>
                <td>{p.builtin ? "built in" : (p.created_by ?? "")}</td>
                <td className="nowrap no-print">
                  {operator && (
                    <button type="button" className="primary" data-testid="preset-apply" disabled={busy} onClick={() => ask(p.name)}>
                      Apply…
                    </button>
                  )}
                  {operator && !p.builtin && (
                    <button type="button" data-testid="preset-delete" disabled={busy} onClick={() => remove(p.name)}>
                      Delete
                    </button>
                  )}
                </td>
              </tr>
            ))}
          </tbody>
        </table>
      </div>
      {pending !== null && <ConfirmDialog message={confirmWords(pending)} confirmLabel="Apply" onAnswer={answer} />}
    </div>
  );
});
