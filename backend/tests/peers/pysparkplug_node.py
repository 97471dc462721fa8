"""An edge node we did not write: pysparkplug's ``EdgeNode`` with one ``Device``, run by the
plant's tests in a venv of its own (pysparkplug 0.6.1 needs paho-mqtt 1.x, the product 2.x:
``make`` installs it into ``.venv/pysparkplug-peer``). Driven by lines on stdin:

- ``data DEVICE METRIC JSON``: a DDATA of that metric (its datatype from the birth);
- ``gap``: the next seq is skipped (a message the plant never sees);
- ``death``: NDEATH (pysparkplug's clean disconnect publishes it), then exit.

It prints ``ready`` once born and ``ncmd NAME=VALUE,...`` for each NCMD it receives; on a
``Node Control/Rebirth`` it is born again (pysparkplug has no rebirth of its own: it disconnects
and connects, which sends NBIRTH and DBIRTH with every metric's current value and time).
"""

from __future__ import annotations

import json
import sys
import threading
import time

import pysparkplug as sp

ALARM = "Alarm/overheat"


def main() -> int:
    host, port, group, node_id, device_id = sys.argv[1], int(sys.argv[2]), *sys.argv[3:6]
    now = sp.get_current_timestamp

    rebirth = threading.Event()

    def on_command(_node: sp.EdgeNode, message: sp.Message) -> None:
        names = ",".join(f"{m.name}={m.value}" for m in message.payload.metrics)
        print(f"ncmd {names}", flush=True)
        if any(m.name == "Node Control/Rebirth" and m.value for m in message.payload.metrics):
            rebirth.set()

    node = sp.EdgeNode(
        group,
        node_id,
        [sp.Metric(now(), "Node Info/Area", sp.DataType.STRING, value="paint shop")],
        client=sp.Client(client_id=f"pysparkplug-{node_id}"),
        cmd_callback=on_command,
    )
    datatypes = {
        "robot_state": sp.DataType.STRING,
        f"{ALARM}/Active": sp.DataType.BOOLEAN,
        f"{ALARM}/Priority": sp.DataType.STRING,
        f"{ALARM}/Text": sp.DataType.STRING,
        "Cycle/Last": sp.DataType.DOUBLE,
    }
    initial = {
        "robot_state": "STANDALONE_RUNNING",
        f"{ALARM}/Active": False,
        f"{ALARM}/Priority": "high",
        f"{ALARM}/Text": "Motor overheated",
        "Cycle/Last": 12.5,
    }
    node.register(
        sp.Device(
            device_id, [sp.Metric(now(), n, datatypes[n], value=v) for n, v in initial.items()]
        )
    )
    node.connect(host, port=port, blocking=False)

    def rebirths() -> None:  # off paho's thread: disconnect stops its loop
        while True:
            rebirth.wait()
            rebirth.clear()
            node.disconnect()
            node.connect(host, port=port, blocking=False)
            print("reborn", flush=True)

    threading.Thread(target=rebirths, daemon=True).start()
    time.sleep(0.5)
    print("ready", flush=True)
    for line in sys.stdin:
        words = line.split(maxsplit=3)
        if not words:
            continue
        if words[0] == "data":
            device, name, value = words[1], words[2], json.loads(words[3])
            node.update_device(device, [sp.Metric(now(), name, datatypes[name], value=value)])
        elif words[0] == "gap":
            next(node._EdgeNode__seq_cycler)  # type: ignore[attr-defined]
        elif words[0] == "death":
            node.disconnect()
            return 0
        print(f"done {words[0]}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
