/**
 * One joint's card on the health page: its verdict in words on its colour, the reason in a
 * sentence, its figures with their units and its reducer's life used as a bar with the life
 * left in hours and as a date (lib/health/figures.ts says each in words).
 */
import type { JointHealth } from "../lib/health/healthTypes";
import { jointFigures, lifeBar } from "../lib/health/figures";
import { VERDICT_MEANING, VERDICT_WORDS, verdictPaint } from "../lib/health/verdicts";

export function VerdictBadge({ verdict, testId, large = false }: { readonly verdict: JointHealth["verdict"]; readonly testId: string; readonly large?: boolean }) {
  const paint = verdictPaint(verdict);
  return (
    <span
      className={`verdict${large ? " verdict--large" : ""}`}
      data-testid={testId}
      data-verdict={verdict}
      style={{ background: paint.background, color: paint.text }}
      title={VERDICT_MEANING[verdict]}
    >
      {VERDICT_WORDS[verdict]}
    </span>
  );
}

function LifeBar({ joint }: { readonly joint: JointHealth }) {
  const bar = lifeBar(joint);
  return (
    <div className="health-life">
      <div className="health-life__words">
        <span>reducer life</span> <strong data-testid={`health-life-used-${joint.joint}`}>{bar.usedWords}</strong>
      </div>
      <div
        className="health-life__bar"
        role="meter"
        aria-label={`J${joint.joint} reducer life used`}
        aria-valuemin={0}
        aria-valuemax={100}
        aria-valuenow={Number(bar.fill_percent.toFixed(2))}
        aria-valuetext={`${bar.usedWords}; ${bar.remainingWords}`}
        data-testid={`health-life-bar-${joint.joint}`}
      >
        {/* At least a sliver: a life just begun still shows where the bar starts. */}
        <span className="health-life__fill" style={{ width: `${Math.max(bar.fill_percent, 0.5)}%` }} />
      </div>
      <div className="health-life__left" data-testid={`health-life-left-${joint.joint}`}>
        {bar.remainingWords}
      </div>
    </div>
  );
}

export function JointCard({ joint }: { readonly joint: JointHealth }) {
  const headingId = `health-card-${joint.joint}-title`;
  return (
    <article className={`health-card health-card--${joint.verdict}`} data-testid="health-card" data-joint={joint.joint} data-verdict={joint.verdict} aria-labelledby={headingId}>
      <header className="health-card__header">
        <h3 id={headingId}>J{joint.joint}</h3>
        <VerdictBadge verdict={joint.verdict} testId="health-card-verdict" />
      </header>
      <p className="health-card__reason" data-testid="health-card-reason">
        {joint.reason}
      </p>
      <dl className="health-card__figures">
        {jointFigures(joint).map((figure) => (
          <div key={figure.key}>
            <dt>{figure.label}</dt>
            <dd data-testid={`health-figure-${figure.key}`} data-value={figure.raw ?? ""}>
              {figure.value}
            </dd>
          </div>
        ))}
      </dl>
      <LifeBar joint={joint} />
    </article>
  );
}
