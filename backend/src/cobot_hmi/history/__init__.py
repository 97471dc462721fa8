"""Layer: history storage (above the codec, beside ``enip``). Imports only the layout and the
codec; must not import ``enip``, ``emulator``, ``scanner``, ``service`` or ``cli``, so the service
(recorder, REST), the command line (``cobot-hmi export``) and the emulator (``--replay``) can all
read and write recordings.

One concern per module: ``schema`` (the columns, derived from the layout), ``segments`` (the
crash-safe segment writer and the directory of segments), ``rollup`` (per-second min/max/first/
last cells), ``query`` (decimated ranges), ``retention`` (age and size), ``export`` (CSV,
Parquet, MCAP, streamed), ``recording`` (reading an export back for replay), ``times`` (ISO 8601
or epoch seconds). The storage choice is argued in docs/architecture.md ("History").
"""
