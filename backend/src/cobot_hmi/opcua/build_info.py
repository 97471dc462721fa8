"""Layer: service (OPC UA). What the server says it is: BuildInfo and the application type.

asyncua's ``Server.init`` writes its own BuildInfo ("FreeOpcUa Python Server", version
"1.0pre", built now) and describes itself as ``ClientAndServer``. ``describe`` replaces both
with this product's: ``Server_ServerStatus_BuildInfo`` (OPC 10000-5 §12.4: ProductUri,
ManufacturerName, ProductName, SoftwareVersion, BuildNumber, BuildDate) names cobot-hmi and the
version ``cobot-hmi --version`` and the OpenAPI document give, and the endpoints'
``ApplicationDescription`` says ``Server`` (it is never an OPC UA client).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Final

from asyncua import Server, ua

from cobot_hmi import __version__

PRODUCT_NAME: Final = "cobot-hmi"
MANUFACTURER_NAME: Final = "The cobot-hmi project"
DISTRIBUTION: Final = "cobot-hmi"


@dataclass(frozen=True, slots=True)
class BuildInfo:
    """The product's BuildInfo, as OPC UA's ``BuildInfo`` structure carries it."""

    product_uri: str
    software_version: str
    build_number: str
    build_date: datetime


def build_date() -> datetime:
    """When this installation of the package was built: the modification time of its
    distribution's ``METADATA`` (written when pip built and installed it, wheel or editable).
    Not the start time, as asyncua's was: the same installation gives the same date at every
    start, and a new build a new one. Without an installed distribution (the sources on
    ``PYTHONPATH``): the time of this package's own files."""
    try:
        files = metadata.distribution(DISTRIBUTION).files or []
    except metadata.PackageNotFoundError:
        files = []
    found = [Path(str(f.locate())) for f in files if f.name == "METADATA"]
    path = found[0] if found else None
    if path is None or not path.is_file():
        path = Path(__file__).parent.parent / "__init__.py"
    return datetime.fromtimestamp(path.stat().st_mtime, UTC)


def build_info(product_uri: str) -> BuildInfo:
    return BuildInfo(product_uri, __version__, __version__, build_date())


async def describe(server: Server, info: BuildInfo) -> None:
    """Write ``info`` into the server's BuildInfo (after ``init``) and make it a ``Server``
    application (before ``start``, which builds the endpoints)."""
    server.application_type = ua.ApplicationType.Server
    server.manufacturer_name = MANUFACTURER_NAME
    await server.set_build_info(
        info.product_uri,
        MANUFACTURER_NAME,
        PRODUCT_NAME,
        info.software_version,
        info.build_number,
        info.build_date,
    )
