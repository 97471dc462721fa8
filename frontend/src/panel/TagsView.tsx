/**
 * Tag names of the robot shown: every I/O point and bit register with its label (DO 3) and its
 * name ("gripper close"); an admin edits them here or imports a CSV (`key,label,name`, as the
 * export writes it). Everyone who may view sees them. Names are kept by the service per robot
 * (docs/api.md "Tag names") and shown beside the label in events, audit rows and alarms.
 */
import { memo, useEffect, useMemo, useState, type ChangeEvent } from "react";
import { tagLabel } from "../lib/alarms/alarms";
import { alarmsApi, tagsCsvUrl, type TagList } from "../lib/alarms/alarmsApi";
import { roleAtLeast, type User } from "../lib/api/protocol";
import { tagChanges, type TagNames } from "../lib/layout/tags";

export const TagsView = memo(function TagsView({
  robot,
  user,
  onTags,
}: {
  readonly robot: string;
  readonly user: User | null;
  /** The names as the service has them now (after loading, saving or importing), for the rest of the panel. */
  readonly onTags: (tags: TagNames) => void;
}) {
  const [list, setList] = useState<TagList | null>(null);
  const [draft, setDraft] = useState<Readonly<Record<string, string>>>({});
  const [filter, setFilter] = useState("");
  const [error, setError] = useState<string | null>(null);
  const [note, setNote] = useState<string | null>(null);
  const [busy, setBusy] = useState(false);
  const [reload, setReload] = useState(0);
  const admin = roleAtLeast(user, "admin");

  useEffect(() => {
    let cancelled = false;
    alarmsApi
      .tags(robot)
      .then((answer) => {
        if (cancelled) return;
        if (answer.ok) {
          setList(answer.page);
          setDraft(answer.page.tags);
          setError(null);
          onTags(answer.page.tags);
        } else setError(`tag names: ${answer.reason}`);
      })
      .catch((e: unknown) => !cancelled && setError(String(e)));
    return () => {
      cancelled = true;
    };
  }, [robot, reload, user, onTags]);

  const changes = useMemo(() => (list === null ? 0 : tagChanges(list.tags, draft)), [list, draft]);
  const points = useMemo(() => {
    const q = filter.trim().toLowerCase();
    const all = list?.points ?? [];
    if (q === "") return all;
    return all.filter((p) => p.label.toLowerCase().includes(q) || p.key.includes(q) || (draft[p.key] ?? "").toLowerCase().includes(q));
  }, [list, filter, draft]);

  const applied = (answer: Awaited<ReturnType<typeof alarmsApi.putTags>>, words: string) => {
    if (answer.ok) {
      setList(answer.page);
      setDraft(answer.page.tags);
      setError(null);
      setNote(words);
      onTags(answer.page.tags);
    } else setError(answer.reason);
  };

  const save = async () => {
    setBusy(true);
    setNote(null);
    try {
      applied(await alarmsApi.putTags(robot, draft), "saved");
    } catch (e) {
      setError(String(e));
    } finally {
      setBusy(false);
    }
  };

  const importFile = async (e: ChangeEvent<HTMLInputElement>) => {
    const file = e.target.files?.[0];
    e.target.value = "";
    if (file === undefined) return;
    setBusy(true);
    setNote(null);
    try {
      applied(await alarmsApi.importTags(robot, await file.text()), `imported ${file.name}`);
    } catch (x) {
      setError(String(x));
    } finally {
      setBusy(false);
    }
  };

  return (
    <div className="table-view tags-view">
      <div className="table-view__bar">
        <label>
          find{" "}
          <input data-testid="tags-filter" value={filter} placeholder="DO 3, register, gripper…" onChange={(e) => setFilter(e.target.value)} />
        </label>
        <span className="table-view__source">
          {list !== null ? `${Object.keys(list.tags).length} of ${list.points.length} points named` : "loading…"}
          {!admin && " · an admin can name them"}
        </span>
        <a data-testid="tags-csv" href={tagsCsvUrl(robot)} download={`${robot}-tags.csv`}>
          Export CSV
        </a>
        {admin && (
          <>
            <label className="tags-view__import">
              Import CSV <input type="file" accept=".csv,text/csv" data-testid="tags-import-file" disabled={busy} onChange={(e) => void importFile(e)} />
            </label>
            <button type="button" className="primary" data-testid="tags-save" disabled={busy || changes === 0} onClick={() => void save()}>
              Save {changes > 0 ? `(${changes})` : ""}
            </button>
            <button type="button" disabled={busy || changes === 0} onClick={() => list !== null && setDraft(list.tags)}>
              Undo changes
            </button>
          </>
        )}
        {note !== null && <span data-testid="tags-note">{note}</span>}
        {error !== null && (
          <span className="reason" role="alert" data-testid="tags-error">
            {error}{" "}
            <button type="button" onClick={() => setReload((n) => n + 1)}>
              Reload
            </button>
          </span>
        )}
      </div>
      <div className="table-scroll" tabIndex={0} role="region" aria-label="Tag names">
        <table data-testid="tags-table">
          <thead>
            <tr>
              <th>point</th>
              <th>key (API, 0-based)</th>
              <th>name</th>
              <th>shown as</th>
            </tr>
          </thead>
          <tbody>
            {points.map((p) => (
              <tr key={p.key} data-testid="tag-row" data-key={p.key}>
                <td className="nowrap">{p.label}</td>
                <td>
                  <code>{p.key}</code>
                </td>
                <td>
                  {admin ? (
                    <input
                      aria-label={`Name of ${p.label}`}
                      data-testid="tag-name"
                      value={draft[p.key] ?? ""}
                      maxLength={64}
                      onChange={(e) => setDraft({ ...draft, [p.key]: e.target.value })}
                    />
                  ) : (
                    (list?.tags[p.key] ?? "")
                  )}
                </td>
                <td>{tagLabel(p.label, draft[p.key])}</td>
              </tr>
            ))}
          </tbody>
        </table>
      </div>
    </div>
  );
});
