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
import queue
import sys
import threading
import time

import pysparkplug as sp

ALARM = "Alarm/overheat"


def main() -> int:
    host, port, group, node_id, device_id = sys.argv[1], int(sys.argv[2]), *sys.argv[3:6]
    now = sp.get_current_timestamp

    # One thread does everything to the node, in order: the commands read from stdin and the
    # rebirths asked for (paho 1.x's publish and disconnect on two threads at once can lock up).
    work: queue.Queue[str] = queue.Queue()

    def on_command(_node: sp.EdgeNode, message: sp.Message) -> None:
        names = ",".join(f"{m.name}={m.value}" for m in message.payload.metrics)
        print(f"ncmd {names}", flush=True)
        if any(m.name == "Node Control/Rebirth" and m.value for m in message.payload.metrics):
            work.put("rebirth")

    node = sp.EdgeNode(
        group,
        node_id,
        [sp.Metric(now(), "Node Info/Area", sp.DataType.STRING, value="paint shop")],
        # Back within 2 s when its broker drops it (pysparkplug's default waits up to 120 s).
        client=sp.Client(
            client_id=f"pysparkplug-{node_id}",
            client_options=sp.ClientOptions(reconnection_delay_max=2),
        ),
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

    def read_stdin() -> None:
        for line in sys.stdin:
            work.put(line)
        work.put("death")

    threading.Thread(target=read_stdin, daemon=True).start()
    time.sleep(0.5)
    print("ready", flush=True)
    while True:
        line = work.get()
        words = line.split(maxsplit=3)
        if not words:
            continue
        if words[0] == "rebirth":  # off paho's thread: disconnect stops its loop
            node.disconnect()
            node.connect(host, port=port, blocking=False)
            print("reborn", flush=True)
            continue
        if words[0] == "data":
            device, name, value = words[1], words[2], json.loads(words[3])
            node.update_device(device, [sp.Metric(now(), name, datatypes[name], value=value)])
        elif words[0] == "gap":
            next(node._EdgeNode__seq_cycler)  # its private seq counter: a planted gap
        elif words[0] == "death":
            node.disconnect()
            return 0
        print(f"done {words[0]}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
