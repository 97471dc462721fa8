/**
 * The plant page (`/plant`, where `cobot-hmi plant` sends `/`): every cell (a Sparkplug edge
 * node) and its robots at a glance, filterable by area (Sparkplug group) and state; the plant's
 * alarm list with each cell's ISA-18.2 figures; each robot's shift. Read only; live by polling
 * the plant's REST API (lib/plant/plantApi.ts). What each row says is lib/plant/plant.ts; how
 * it fits a 1920 × 1080 wall display without scrolling and a phone is styles/plant.css and the
 * density chosen from the number of robots.
 */
import { useEffect, useMemo, useState, useSyncExternalStore, type CSSProperties, type FormEvent } from "react";
import {
  STATE_FILTERS,
  STATE_GROUPS,
  alarmLines,
  areasOf,
  badActorWords,
  cellCards,
  densityFor,
  downPeerWords,
  downPeers,
  stateCounts,
  type CellCard,
  type PlantFilter,
  type RobotRow,
  type StateFilter,
} from "../lib/plant/plant";
import { PlantPoller, plantApi } from "../lib/plant/plantApi";
import { formatMoment } from "../lib/common/dates";
import "../styles/plant.css";

function paintStyle(paints: RobotRow["state"]["paints"]): CSSProperties {
  const first = paints[0];
  const second = paints[1] ?? first;
  return {
    "--badge-bg-0": first?.background,
    "--badge-fg-0": first?.text,
    "--badge-bg-1": second?.background,
    "--badge-fg-1": second?.text,
  } as CSSProperties;
}

function ShiftBar({ row }: { row: RobotRow }) {
  if (row.shift === null) return null;
  return (
    <span className="plant-shift" data-testid="plant-shift" title={`This shift: ${row.shift.words}`} aria-label={`This shift: ${row.shift.words}`}>
      <span className="plant-shift__bar" aria-hidden="true">
        {STATE_GROUPS.map((group, i) => (
          <span key={group} className={`plant-shift__part plant-shift__part--${group}`} style={{ flexGrow: row.shift!.fractions[i] ?? 0 }} />
        ))}
      </span>
      <span className="plant-shift__count">
        {row.shift.cycles} cyc · {row.shift.meanCycleWords}
      </span>
    </span>
  );
}

function Robot({ row }: { row: RobotRow }) {
  const name = row.panelHref !== null ? <a href={row.panelHref}>{row.device}</a> : row.device;
  const history =
    row.historyHref !== null ? (
      <a className="plant-robot__history" href={row.historyHref} data-testid="plant-robot-history" title={`${row.device}'s recorded frames over this shift, in its cell`}>
        history
      </a>
    ) : null;
  return (
    <li
      className={`plant-robot${row.online ? "" : " is-offline"}`}
      data-testid="plant-robot"
      data-robot={row.device}
      data-cell={row.node}
      data-state-name={row.state.name ?? ""}
      data-state-group={row.stateGroup ?? ""}
      data-online={row.online ? "true" : "false"}
    >
      <span className="plant-robot__name">
        {name} {history}
      </span>
      <span
        className={`plant-robot__state${row.state.alternating ? " is-alternating" : ""}`}
        style={paintStyle(row.state.paints)}
        data-testid="plant-robot-state"
        title={row.state.name ?? undefined}
      >
        {row.state.words}
      </span>
      {row.topAlarm !== null && (
        <span
          className="plant-robot__alarm"
          data-testid="plant-robot-alarm"
          data-priority={row.topAlarm.priority}
          style={{ background: row.topAlarm.paint.background, color: row.topAlarm.paint.text }}
          title={`${row.topAlarm.priority}: ${row.topAlarm.text}${row.alarmCount > 1 ? ` (+${row.alarmCount - 1} more)` : ""}`}
        >
          {row.topAlarm.text}
          {row.alarmCount > 1 ? ` +${row.alarmCount - 1}` : ""}
        </span>
      )}
      <span className="plant-robot__facts">
        <span data-testid="plant-robot-cycle" title="last cycle / average cycle">
          {row.cycleLastWords} / {row.cycleAverageWords}
        </span>
        {!row.online && <span className="plant-robot__since">{row.sinceWords}</span>}
        <ShiftBar row={row} />
        {row.healthWords !== null && (
          <span className="plant-robot__health" data-testid="plant-robot-health" title={`health: ${row.healthWords}`}>
            {row.healthWords}
          </span>
        )}
      </span>
    </li>
  );
}

function Cell({ card }: { card: CellCard }) {
  return (
    <section
      className={`plant-cell${card.online && !card.peerDown ? "" : " is-offline"}${card.figures?.flood === true ? " is-flood" : ""}`}
      data-testid="plant-cell"
      data-peer={card.peer ?? ""}
      data-peer-down={card.peerDown ? "true" : "false"}
      data-group={card.group}
      data-cell={card.node}
      data-online={card.online ? "true" : "false"}
      aria-label={`Cell ${card.node} (${card.group})`}
    >
      <header className="plant-cell__header">
        <h2>{card.node}</h2>
        <span className="plant-cell__area">{card.area ?? card.group}</span>
        <span className="plant-cell__since" data-testid="plant-cell-since">
          {card.sinceWords}
        </span>
        <span className="plant-cell__figures" data-testid="plant-cell-figures" data-flood={card.figures?.flood === true ? "true" : "false"}>
          {card.figuresWords}
        </span>
        <nav className="plant-cell__links" aria-label={`Cell ${card.node}: its pages`}>
          {card.hmiHref !== null && (
            <a href={card.hmiHref} data-testid="plant-cell-hmi">
              HMI
            </a>
          )}
          {card.historyHref !== null && (
            <a href={card.historyHref} data-testid="plant-cell-history" title="the cell's history over this shift: its recorded frames, in its panel">
              History
            </a>
          )}
        </nav>
      </header>
      <ul className="plant-cell__robots">
        {card.robots.map((row) => (
          <Robot key={row.key} row={row} />
        ))}
      </ul>
    </section>
  );
}

function Login({ onDone }: { onDone: () => void }) {
  const [error, setError] = useState<string | null>(null);
  const submit = (event: FormEvent<HTMLFormElement>) => {
    event.preventDefault();
    const data = new FormData(event.currentTarget);
    void plantApi.login(String(data.get("username") ?? ""), String(data.get("password") ?? "")).then((answer) => {
      if (answer.ok) onDone();
      else setError(answer.reason);
    });
  };
  return (
    <form className="plant-login" onSubmit={submit} data-testid="plant-login">
      <p>The plant asks for a login to show its cells.</p>
      <label>
        User <input name="username" autoComplete="username" required />
      </label>
      <label>
        Password <input name="password" type="password" autoComplete="current-password" required />
      </label>
      <button type="submit">Log in</button>
      {error !== null && <span role="alert">{error}</span>}
    </form>
  );
}

function useViewport(): { width: number; height: number } {
  const [size, setSize] = useState(() => ({ width: window.innerWidth, height: window.innerHeight }));
  useEffect(() => {
    const onResize = () => setSize({ width: window.innerWidth, height: window.innerHeight });
    window.addEventListener("resize", onResize);
    return () => window.removeEventListener("resize", onResize);
  }, []);
  return size;
}

/** The cells' columns at a width (styles/plant.css: the aside takes 440 px beside them). */
const CELL_COLUMN_PX = 330;
const ASIDE_PX = 440;
const WIDE_PX = 1000;

export function PlantApp() {
  const poller = useMemo(() => new PlantPoller(plantApi), []);
  useEffect(() => {
    poller.start();
    return () => poller.stop();
  }, [poller]);
  const plant = useSyncExternalStore(poller.subscribe, poller.getSnapshot);
  const [filter, setFilter] = useState<PlantFilter>({ area: null, state: null });
  const viewport = useViewport();
  const now_ms = plant.answered_ms || Date.now();
  const range = { since_s: plant.shifts?.since ?? now_ms / 1000 - 8 * 3600, until_s: now_ms / 1000 };
  const cards = cellCards(plant.nodes, plant.alarms?.figures ?? [], plant.shifts?.robots ?? [], filter, range, now_ms, plant.shifts?.time_zone, downPeers(plant.peers));
  const peersDown = downPeerWords(plant.peers, now_ms, plant.shifts?.time_zone);
  const robots = cards.reduce((n, c) => n + c.robots.length, 0);
  const wide = viewport.width >= WIDE_PX;
  const columns = wide ? Math.max(1, Math.floor((viewport.width - ASIDE_PX - 32) / CELL_COLUMN_PX)) : 1;
  const density = wide ? densityFor(robots, cards.length, columns, viewport.height - 110) : "roomy";
  const counts = stateCounts(plant.nodes, filter.area);
  const lines = alarmLines(plant.alarms?.transitions ?? [], filter.area, now_ms, plant.shifts?.time_zone);
  const figures = (plant.alarms?.figures ?? []).filter((f) => filter.area === null || f.group === filter.area);

  return (
    <div className="plant" data-testid="plant" data-density={density} data-robots={robots}>
      <header className="plant__header">
        <h1>Plant</h1>
        <span className="plant__count" data-testid="plant-count">
          {plant.loaded ? `${cards.length} cell${cards.length === 1 ? "" : "s"}, ${robots} robot${robots === 1 ? "" : "s"}` : "asking the plant…"}
        </span>
        <label className="plant__area">
          Area{" "}
          <select
            data-testid="plant-area"
            value={filter.area ?? ""}
            onChange={(e) => setFilter({ ...filter, area: e.target.value === "" ? null : e.target.value })}
          >
            <option value="">all</option>
            {areasOf(plant.nodes).map((area) => (
              <option key={area} value={area}>
                {area}
              </option>
            ))}
          </select>
        </label>
        <div className="plant__states" role="group" aria-label="State">
          {STATE_FILTERS.map((state: StateFilter) => (
            <button
              key={state}
              type="button"
              className={`plant__state plant__state--${state}`}
              aria-pressed={filter.state === state}
              data-testid={`plant-filter-${state}`}
              onClick={() => setFilter({ ...filter, state: filter.state === state ? null : state })}
            >
              {state} {counts[state]}
            </button>
          ))}
        </div>
        {plant.shifts !== null && (
          <span className="plant__range" data-testid="plant-range">
            shift since {formatMoment(plant.shifts.since * 1000, now_ms, plant.shifts.time_zone)} ({plant.shifts.time_zone})
          </span>
        )}
      </header>
      {plant.error !== null && !plant.loginNeeded && (
        <div className="stale-banner" role="alert" data-testid="plant-error">
          {plant.stale ? "Not current: " : ""}the plant did not answer: {plant.error}
        </div>
      )}
      {peersDown.map((words) => (
        <div key={words} className="stale-banner" role="status" data-testid="plant-peer-down">
          {words}
        </div>
      ))}
      {plant.loginNeeded && <Login onDone={() => poller.restart()} />}
      <main className="plant__cells" data-testid="plant-cells">
        {cards.map((card) => (
          <Cell key={card.key} card={card} />
        ))}
      </main>
      <aside className="plant__alarms" aria-label="Plant alarms" data-testid="plant-alarms">
        <h2>Alarms</h2>
        <table className="plant-figures" data-testid="plant-figures">
          <caption>ISA-18.2 this shift, per cell</caption>
          <tbody>
            {figures.map((f) => (
              <tr key={`${f.group}/${f.node}`} data-cell={f.node} data-flood={f.flood ? "true" : "false"} className={f.flood ? "is-flood" : ""}>
                <th scope="row">{f.node}</th>
                <td>
                  {f.flood ? <strong>FLOOD {f.peak_per_10_min} in 10 min</strong> : null} {f.alarms_per_10_min.toFixed(1)} per 10 min
                </td>
                <td className="plant-figures__actors">
                  {f.bad_actors.length > 0 && (
                    <details data-testid="plant-bad-actors">
                      <summary title="the top ten bad actors this shift">{badActorWords(f).slice(0, 2).join(", ")}{f.bad_actors.length > 2 ? ", …" : ""}</summary>
                      <ol>
                        {badActorWords(f).map((words) => (
                          <li key={words}>{words}</li>
                        ))}
                      </ol>
                    </details>
                  )}
                </td>
              </tr>
            ))}
          </tbody>
        </table>
        <ol className="plant-alarm-list" data-testid="plant-alarm-list">
          {lines.map((line) => (
            <li key={line.key} className={`plant-alarm${line.active ? "" : " is-cleared"}`} data-testid="plant-alarm" data-cell={line.cell} data-robot={line.robot} data-priority={line.priority}>
              <span className="plant-alarm__priority" style={{ background: line.paint.background, color: line.paint.text }}>
                {line.priority}
              </span>
              <span className="plant-alarm__time">{line.timeWords}</span>
              <span className="plant-alarm__where">
                {line.cell} · {line.robot}
              </span>
              <span className="plant-alarm__text">
                {line.text} <em>{line.transitionWords}</em>
              </span>
            </li>
          ))}
        </ol>
      </aside>
    </div>
  );
}
