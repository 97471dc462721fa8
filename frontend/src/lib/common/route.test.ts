import { describe, expect, it } from "vitest";
import { chooseRobot, faceOf, healthHref, historyHref, kioskHref, panelHref, rangeFromSearch, robotFromSearch, searchWithRobot } from "./route";

describe("faceOf", () => {
  it("routes /kiosk, /fleet and everything else to the panel", () => {
    expect(faceOf("/kiosk")).toBe("kiosk");
    expect(faceOf("/kiosk/")).toBe("kiosk");
    expect(faceOf("/fleet")).toBe("fleet");
    expect(faceOf("/fleet/")).toBe("fleet");
    expect(faceOf("/")).toBe("panel");
    expect(faceOf("/fleety")).toBe("panel");
    expect(faceOf("/kiosk/fleet")).toBe("panel");
  });

  it("routes /health to a robot's health page, linked by its name", () => {
    expect(faceOf("/health")).toBe("health");
    expect(faceOf("/health/")).toBe("health");
    expect(faceOf("/healthz")).toBe("panel");
    expect(healthHref("m1013")).toBe("/health?robot=m1013");
  });

  it("routes /plant to the plant page (where cobot-hmi plant sends /)", () => {
    expect(faceOf("/plant")).toBe("plant");
    expect(faceOf("/plant/")).toBe("plant");
    expect(faceOf("/plants")).toBe("panel");
  });
});

describe("robot in the URL", () => {
  it("reads ?robot= and ignores names the service could not have", () => {
    expect(robotFromSearch("?robot=m1013")).toBe("m1013");
    expect(robotFromSearch("?token=x&robot=cell_2-b")).toBe("cell_2-b");
    expect(robotFromSearch("")).toBeNull();
    expect(robotFromSearch("?robot=")).toBeNull();
    expect(robotFromSearch("?robot=Upper")).toBeNull();
    expect(robotFromSearch("?robot=a%2Fb")).toBeNull();
    expect(robotFromSearch(`?robot=${"a".repeat(33)}`)).toBeNull();
  });

  it("sets and removes ?robot= keeping the other parameters", () => {
    expect(searchWithRobot("", "a")).toBe("?robot=a");
    expect(searchWithRobot("?token=t&robot=a", "b")).toBe("?token=t&robot=b");
    expect(searchWithRobot("?robot=a", null)).toBe("");
    expect(searchWithRobot("?token=t&robot=a", null)).toBe("?token=t");
  });

  it("links the faces to one robot", () => {
    expect(panelHref("m0609")).toBe("/?robot=m0609");
    expect(kioskHref("m0609")).toBe("/kiosk?robot=m0609");
  });
});

describe("chooseRobot", () => {
  it("takes the URL's robot before the list is known", () => {
    expect(chooseRobot("b", null)).toEqual({ robot: "b", unknown: null });
    expect(chooseRobot(null, null)).toEqual({ robot: null, unknown: null });
  });

  it("takes the URL's robot when the service knows it, else the default (first) one", () => {
    expect(chooseRobot("b", ["a", "b"])).toEqual({ robot: "b", unknown: null });
    expect(chooseRobot(null, ["a", "b"])).toEqual({ robot: "a", unknown: null });
    expect(chooseRobot("ghost", ["a", "b"])).toEqual({ robot: "a", unknown: "ghost" });
    expect(chooseRobot("ghost", [])).toEqual({ robot: null, unknown: "ghost" });
  });
});

describe("a range in the URL (the plant page's History link)", () => {
  it("reads from and to in epoch seconds, the end after the start", () => {
    expect(rangeFromSearch("?robot=m1013&from=1764547200&to=1764576000")).toEqual({ from_s: 1764547200, to_s: 1764576000 });
    expect(rangeFromSearch("?from=10.5&to=11")).toEqual({ from_s: 10.5, to_s: 11 });
  });
  it("names none when a bound is missing, empty, not a number or not after the start", () => {
    for (const search of ["", "?robot=m1013", "?from=10", "?to=10", "?from=&to=10", "?from=a&to=10", "?from=10&to=10", "?from=11&to=10"]) {
      expect(rangeFromSearch(search)).toBeNull();
    }
  });
  it("is what historyHref writes", () => {
    const href = historyHref("m1013", 1764547200.4, 1764576000);
    expect(href).toBe("/?robot=m1013&from=1764547200&to=1764576000");
    const search = href.slice(1);
    expect(robotFromSearch(search)).toBe("m1013");
    expect(rangeFromSearch(search)).toEqual({ from_s: 1764547200, to_s: 1764576000 });
  });
});
