/**
 * A robot's health page (`/health?robot=NAME`, issue 40; docs/health.md): a card per joint with
 * its verdict (ok / watch / act, in words on its colour), the reason in a sentence, its figures
 * and its reducer's life used; the trend over days; this shift's knocks on the arm's
 * joint-space picture; the baselines with who set them and why, and the form for a new one
 * (operators). Printed, it is the weekly health report (styles/health.css); the same report as
 * CSV is a download link. The report is polled every few seconds (lib/common/poller.ts).
 */
import { useCallback, useEffect, useMemo, useState, useSyncExternalStore } from "react";
import { ThemeSwitch, useTheme } from "../components/theme";
import { api } from "../lib/api/api";
import type { User } from "../lib/api/protocol";
import { formatDateTime_ms, formatTimestamp } from "../lib/common/dates";
import { FLEET_HREF, chooseRobot, healthHref, kioskHref, panelHref, robotFromSearch } from "../lib/common/route";
import { healthApi } from "../lib/health/healthApi";
import { Poller } from "../lib/common/poller";
import { HEALTH_POLL_MS } from "../lib/health/healthApi";
import type { HealthAnswer } from "../lib/health/healthTypes";
import { maintenanceMark } from "../lib/health/maintenanceMark";
import { isVerdict, robotVerdictWords, worstVerdict } from "../lib/health/verdicts";
import { lastWeek, reportCsvName, reportCsvUrl, reportTitle } from "../lib/health/weeklyReport";
import { BaselinesView } from "./BaselinesView";
import { HealthLogin } from "./HealthLogin";
import { HealthTrend } from "./HealthTrend";
import { JointCard, VerdictBadge } from "./JointCard";
import { KnocksView } from "./KnocksView";
import "../styles/panel.css";
import "../styles/print.css";
import "../styles/health.css";

function Summary({ report }: { readonly report: HealthAnswer }) {
  const baseline = report.baseline ?? null;
  const learning = report.learning ?? null;
  const cycle = report.cycle_time ?? null;
  return (
    <dl className="health-summary" data-testid="health-summary">
      <div>
        <dt>baseline in use</dt>
        <dd data-testid="health-baseline-in-use" data-id={baseline?.id ?? ""}>
          {baseline === null
            ? "none yet"
            : `#${baseline.id}, learned ${typeof baseline.learned_to === "number" ? formatTimestamp(baseline.learned_to) : "—"} from ${baseline.cycles ?? "?"} cycles: ${baseline.reason} (${baseline.created_by})`}
        </dd>
      </div>
      {learning !== null && (
        <div>
          <dt>learning</dt>
          <dd data-testid="health-learning">
            #{learning.id}: {learning.reason} ({learning.created_by}), {learning.cycles ?? 0}
            {typeof learning.target_cycles === "number" ? ` of ${learning.target_cycles}` : ""} cycles so far
          </dd>
        </div>
      )}
      {cycle !== null && (
        <div>
          <dt>cycle time</dt>
          <dd data-testid="health-cycle-time" data-verdict={cycle.verdict}>
            {isVerdict(cycle.verdict) && <VerdictBadge verdict={cycle.verdict} testId="health-cycle-verdict" />} {cycle.reason}
          </dd>
        </div>
      )}
      <div>
        <dt>cycles read</dt>
        <dd data-testid="health-cycles">{report.cycles ?? "—"}</dd>
      </div>
      <div>
        <dt>report of</dt>
        <dd>{typeof report.time === "number" ? formatTimestamp(report.time) : "—"}</dd>
      </div>
    </dl>
  );
}

function HealthPage({ robot, robots, user, onUser }: { readonly robot: string; readonly robots: readonly string[]; readonly user: User | null; readonly onUser: (user: User | null) => void }) {
  const theme = useTheme();
  const poller = useMemo(() => new Poller(() => healthApi.report(robot), HEALTH_POLL_MS), [robot]);
  useEffect(() => {
    poller.start();
    return () => poller.stop();
  }, [poller]);
  const snapshot = useSyncExternalStore(poller.subscribe, poller.getSnapshot);
  // The baselines change seldom: asked every 10 s, and at once after a re-baselining.
  const baselinesPoller = useMemo(() => new Poller(() => healthApi.baselines(robot), 10_000), [robot]);
  useEffect(() => {
    baselinesPoller.start();
    return () => baselinesPoller.stop();
  }, [baselinesPoller]);
  const baselines = useSyncExternalStore(baselinesPoller.subscribe, baselinesPoller.getSnapshot);
  const onAsked = useCallback(() => {
    poller.refresh();
    baselinesPoller.refresh();
  }, [poller, baselinesPoller]);
  const report = snapshot.value;
  const joints = report?.joints ?? [];
  const worst = report !== null ? (isVerdict(report.verdict) ? report.verdict : worstVerdict(joints)) : null;
  const mark = maintenanceMark(report);
  const [week] = useState(() => lastWeek(Date.now()));

  return (
    <div className="health-page" data-testid="health" data-robot={robot} data-verdict={worst ?? ""} data-maintenance-due={mark.due ? "true" : "false"}>
      <header className="health-page__header">
        <div className="health-page__title">
          <h1>Health of {robot}</h1>
          {worst !== null && <VerdictBadge verdict={worst} testId="health-verdict" large />}
          {report !== null && <span data-testid="health-verdict-words">{robotVerdictWords(joints)}</span>}
          {mark.due && (
            <span className="health-page__due" data-testid="health-maintenance-due" role="status">
              maintenance due
            </span>
          )}
        </div>
        <nav className="health-page__nav" aria-label="other pages">
          {robots.length > 1 && (
            <label>
              <span className="visually-hidden">robot</span>
              <select data-testid="robot-select" value={robot} onChange={(e) => window.location.assign(healthHref(e.target.value))}>
                {robots.map((name) => (
                  <option key={name} value={name}>
                    {name}
                  </option>
                ))}
              </select>
            </label>
          )}
          <a href={panelHref(robot)}>Panel</a>
          <a href={kioskHref(robot)}>Kiosk</a>
          <a href={FLEET_HREF}>Fleet</a>
          <ThemeSwitch />
        </nav>
        <div className="health-page__session">
          <HealthLogin user={user} onUser={onUser} />
        </div>
      </header>
      {snapshot.error !== null && (
        <div className="stale-banner" role="alert" data-testid="health-error" data-status={snapshot.status ?? ""}>
          {snapshot.stale ? "Not current: " : ""}the service did not answer with the robot's health: {snapshot.error}
        </div>
      )}
      <p className="print-only health-page__printed">
        {reportTitle(robot, week)}; printed {formatDateTime_ms(Date.now())}
      </p>
      <main className="health-page__main">
        {report === null ? (
          <p data-testid="health-loading">{snapshot.loaded ? "No health report." : "Asking the service for the robot's health…"}</p>
        ) : (
          <>
            <section id="summary" aria-labelledby="summary-title">
              <h2 id="summary-title">Summary</h2>
              <Summary report={report} />
            </section>
            <section id="joints" aria-labelledby="joints-title">
              <h2 id="joints-title">Joints</h2>
              <div className="health-cards">
                {joints.map((joint) => (
                  <JointCard key={joint.joint} joint={joint} />
                ))}
              </div>
            </section>
            <section id="trend" aria-labelledby="trend-title">
              <h2 id="trend-title">Trend</h2>
              <HealthTrend robot={robot} theme={theme} />
            </section>
            <section id="knocks" aria-labelledby="knocks-title">
              <h2 id="knocks-title">Knocks</h2>
              <KnocksView knocks={report.knocks} arm={report.arm} />
            </section>
            <section id="baselines" aria-labelledby="baselines-title">
              <h2 id="baselines-title">Baselines</h2>
              <BaselinesView robot={robot} user={user} baselines={baselines.value?.items ?? null} error={baselines.error} onAsked={onAsked} />
            </section>
            <section id="report" aria-labelledby="report-title" className="no-print">
              <h2 id="report-title">Weekly report</h2>
              <p>
                <button type="button" data-testid="health-print" onClick={() => window.print()}>
                  Print the weekly report
                </button>{" "}
                <a href={reportCsvUrl(robot, week)} download={reportCsvName(robot, week)} data-testid="health-csv">
                  The week as CSV
                </a>
              </p>
            </section>
          </>
        )}
      </main>
    </div>
  );
}

export function HealthApp() {
  const [wanted] = useState(() => robotFromSearch(window.location.search));
  const [user, setUser] = useState<User | null>(null);
  const [known, setKnown] = useState<readonly string[] | null>(null);
  const [error, setError] = useState<string | null>(null);

  useEffect(() => {
    api
      .me()
      .then(setUser)
      .catch(() => setUser(null));
  }, []);
  // The service's robots, asked again after a login (a site may need one to view anything).
  useEffect(() => {
    api
      .robots()
      .then((answer) => {
        if (answer.ok) {
          setKnown(answer.robots.map((r) => r.name));
          setError(null);
        } else setError(answer.reason);
      })
      .catch((err: unknown) => setError(err instanceof Error ? err.message : String(err)));
  }, [user]);

  const { robot, unknown } = chooseRobot(wanted, known);
  useEffect(() => {
    if (robot !== null) document.title = `Health of ${robot} · Cobot HMI`;
  }, [robot]);

  if (robot === null) {
    return (
      <div className="health-page" data-testid="health">
        <header className="health-page__header">
          <h1>Robot health</h1>
          <HealthLogin user={user} onUser={setUser} />
        </header>
        <main className="health-page__main">
          <p className="hint" data-testid="robots-reason">
            {error !== null ? `The robots of the service are unknown: ${error}` : known !== null ? "The service has no robot." : "Asking the service for its robots…"}
          </p>
        </main>
      </div>
    );
  }
  return (
    <>
      {unknown !== null && (
        <div className="stale-banner" role="alert" data-testid="unknown-robot">
          The service has no robot "{unknown}"; showing {robot}.
        </div>
      )}
      <HealthPage key={robot} robot={robot} robots={known ?? [robot]} user={user} onUser={setUser} />
    </>
  );
}
