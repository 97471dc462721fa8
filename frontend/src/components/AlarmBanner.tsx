/**
 * The alarm banner of the panel and the kiosk: the most urgent alarm that needs a person (active
 * before returned, then by priority), in its pendant colour, with the count of the others.
 * Read-only: it shows the live snapshot's alarms (the stream's hello and `alarm` events) and
 * writes nothing; the panel puts its own controls (mute, a link to the list) in `children`.
 * A panel also gives the other robots' alarms (`others`, from the stream's `cell_alarms`): a
 * line each beside the robot's own, naming the robot and linking to its panel.
 */
import type { ReactNode } from "react";
import { alarmPaint, alarmStateWords, alarmTitle, bannerView, countWords, isUnacknowledged, type Alarm, type BannerView } from "../lib/alarms/alarms";
import { otherRobotLine, topUnacknowledged } from "../lib/alarms/alarmsCell";
import { formatMoment } from "../lib/common/dates";
import type { AlarmSummary } from "../lib/api/protocol";
import { panelHref } from "../lib/common/route";
import "../styles/alarms.css";

interface Props {
  readonly alarms: readonly Alarm[];
  readonly size: "panel" | "kiosk";
  /** Where the count links to (the panel's alarm list), undefined: no link. */
  readonly listHref?: string;
  readonly children?: ReactNode;
  /** Other robots of the cell with annunciated alarms (most urgent first), a line each. */
  readonly others?: readonly AlarmSummary[];
}

/** One line per other robot with an alarm, in its most urgent alarm's colour, linking to its panel. */
function OtherRobotLines({ others }: { readonly others: readonly AlarmSummary[] }) {
  if (others.length === 0) return null;
  return (
    <ul className="alarm-banner-others" data-testid="alarm-banner-others" aria-label="Other robots' alarms">
      {others.map((summary) => {
        const robot = summary.robot ?? "?";
        const paint = alarmPaint(summary.top?.colour ?? "");
        const unacknowledged = topUnacknowledged(summary);
        return (
          <li key={robot}>
            <a
              className={`alarm-banner-other${unacknowledged ? " is-unacknowledged" : ""}`}
              data-testid="alarm-banner-other"
              data-robot={robot}
              data-priority={summary.highest_priority ?? ""}
              href={panelHref(robot)}
              title={otherRobotLine(summary)}
              style={{ background: paint.background, color: paint.text }}
            >
              {otherRobotLine(summary)}
            </a>
          </li>
        );
      })}
    </ul>
  );
}

/**
 * The panel's alarms in one row of the header: the robot's own banner, then the other robots'
 * lines beside it (shortened, whole in their titles), so another robot's alarm never adds a row
 * to the sticky header (it must stay within a fifth of the window's height). The kiosk has its
 * banner alone.
 */
export function AlarmBanner(props: Props) {
  const others = props.others ?? [];
  const view = bannerView(props.alarms);
  if (props.size === "kiosk") return <OwnBanner {...props} view={view} />;
  if (view.top === null && others.length === 0) return null;
  return (
    <div className="alarm-banner-row" data-testid="alarm-banner-row">
      <OwnBanner {...props} view={view} />
      <OtherRobotLines others={others} />
    </div>
  );
}

function OwnBanner({ view, size, listHref, children }: Props & { readonly view: BannerView }) {
  const top = view.top;
  if (top === null) return null;
  const paint = alarmPaint(top.colour);
  const unacknowledged = isUnacknowledged(top);
  const others = view.count - 1;
  const count = countWords(view);
  return (
    <div
      className={`alarm-banner alarm-banner--${size}${unacknowledged ? " is-unacknowledged" : ""}${top.active ? "" : " is-returned"}`}
      data-testid="alarm-banner"
      data-alarm={top.id}
      data-priority={top.priority}
      data-colour={top.colour}
      data-state={top.state}
      data-unacknowledged={unacknowledged ? "true" : "false"}
      data-count={view.count}
      role="alert"
      style={{ background: paint.background, color: paint.text }}
    >
      <span className="alarm-banner__priority">{top.priority}</span>
      <span className="alarm-banner__title" data-testid="alarm-banner-title">
        {alarmTitle(top)}
      </span>
      <span className="alarm-banner__state">
        {unacknowledged && (
          <span className="alarm-banner__unack" data-testid="alarm-banner-unack" aria-hidden="true">
            ●
          </span>
        )}{" "}
        {alarmStateWords(top)}
        {top.activated_at !== null ? ` since ${formatMoment(top.activated_at * 1000, Date.now())}` : ""}
      </span>
      {top.message !== null && top.message !== "" && <span className="alarm-banner__message">{top.message}</span>}
      {/* The kiosk's room is dear: a lone alarm's count repeats what its state words say. */}
      {(size === "panel" || others > 0) && (
        <span className="alarm-banner__count" data-testid="alarm-banner-count" title={count}>
          {listHref !== undefined ? <a href={listHref}>{others > 0 ? `+${others} more · ${count}` : count}</a> : others > 0 ? `+${others} more · ${count}` : count}
        </span>
      )}
      {children}
    </div>
  );
}
