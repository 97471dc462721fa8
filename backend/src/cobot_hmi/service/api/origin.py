"""Layer: service. Where a request that is audited came in, as the audit trail names it (its
``origin``: ``POST /api/v1/robots/left/checkouts``), and a commissioning action from it: one
place for every route that audits what it does."""

from __future__ import annotations

from fastapi import Request

from cobot_hmi.service.commissioning.audit import AuditedAction
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.writes.pipeline import Writer


def request_origin(request: Request) -> str:
    """The request's method and path, as the audit trail's ``origin``."""
    return f"{request.method} {request.url.path}"


def audited_action(
    robot: RobotRuntime, writer: Writer, request: Request, action: str
) -> AuditedAction:
    """The robot's commissioning ``action`` (``checkout.result``, ``preset.save`` …) asked by
    this request: authorized and audited by ``AuditedAction``."""
    return AuditedAction(robot.store, writer, robot.name, action, request_origin(request))
