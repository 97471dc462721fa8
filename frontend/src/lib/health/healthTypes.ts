/**
 * Layer: the names of the service's robot-health shapes (docs/health.md, docs/api.md "Health"),
 * as the generated OpenAPI types have them. No React, no DOM.
 */
import type { components } from "../../generated/api";

type Schemas = components["schemas"];

/** `GET /api/v1/robots/{name}/health`. */
export type HealthAnswer = Schemas["HealthReport"];
export type JointHealth = Schemas["HealthJoint"];
export type Verdict = JointHealth["verdict"];
export type JointRating = Schemas["HealthRated"];
/** A baseline's record: who set it, why, and what it was learned from. */
export type BaselineRecord = Schemas["HealthBaseline"];
export type BaselineRequest = Schemas["HealthBaselineCreate"];
export type BaselineList = Schemas["HealthBaselineList"];
export type Knocks = Schemas["HealthKnocks"];
/** A knock: an external-torque peak, a protective or emergency stop, a servo off. */
export type KnockEvent = Schemas["HealthKnock"];
export type CycleTimeHealth = Schemas["HealthCycleTime"];
/** `GET /api/v1/robots/{name}/health/trend`. */
export type TrendAnswer = Schemas["HealthTrend"];
export type TrendPoint = Schemas["HealthTrendPoint"];
export type TrendJoint = Schemas["HealthTrendJoint"];
