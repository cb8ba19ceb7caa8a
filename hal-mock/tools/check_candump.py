#!/usr/bin/env python3
"""Reads a SIL CAN log with python-can's candump reader and checks the CANopen traffic.

Usage: check_candump.py LOG

Checks: every line parses as a standard-id frame or an error frame; timestamps never go
back; each bus
carries SYNC; all 18 drives were started by NMT, answered SDOs, and sent TPDO1/TPDO2
on their own bus (node ids 1-9 on can0, 10-18 on can1).
"""
import sys

import can


def main(path: str) -> int:
    messages = list(can.CanutilsLogReader(path))
    with open(path) as f:
        lines = [line for line in f if line.strip()]
    assert len(messages) == len(lines), f"{len(lines) - len(messages)} lines not read"
    assert messages, "empty log"
    last = 0.0
    syncs = {"can0": 0, "can1": 0}
    error_frames = 0
    started, sdo_answered, tpdo1, tpdo2 = set(), set(), set(), set()
    for m in messages:
        if m.is_error_frame:
            error_frames += 1
            assert m.timestamp >= last, f"time goes back at {m}"
            last = m.timestamp
            continue
        assert not m.is_extended_id, m
        assert m.timestamp >= last, f"time goes back at {m}"
        last = m.timestamp
        cob, data = m.arbitration_id, bytes(m.data)
        if cob == 0x080:
            syncs[m.channel] += 1
            continue
        node = cob & 0x7F
        bus_ok = m.channel == ("can0" if node <= 9 else "can1")
        if cob == 0x000 and len(data) == 2 and data[0] == 0x01:
            started.add(data[1])
        elif 0x581 <= cob <= 0x592 and bus_ok:
            sdo_answered.add(node)
        elif 0x181 <= cob <= 0x192 and bus_ok and len(data) == 6:
            tpdo1.add(node)
        elif 0x281 <= cob <= 0x292 and bus_ok and len(data) == 6:
            tpdo2.add(node)
    nodes = set(range(1, 19))
    assert syncs["can0"] > 0 and syncs["can0"] == syncs["can1"], syncs
    for name, seen in [("NMT start", started), ("SDO", sdo_answered), ("TPDO1", tpdo1), ("TPDO2", tpdo2)]:
        assert seen == nodes, f"{name} missing for nodes {sorted(nodes - seen)}"
    print(f"{path}: {len(messages)} frames ({error_frames} error frames), "
          f"{syncs['can0']} SYNC cycles, 18 drives: ok")
    print_bus_load([m for m in messages if not m.is_error_frame])
    return 0


def frame_bits(dlc: int, worst_case_stuffing: bool) -> int:
    """Bits of a classic CAN 2.0A data frame including interframe space."""
    bits = 47 + 8 * dlc
    if worst_case_stuffing:
        bits += (34 + 8 * dlc - 1) // 4
    return bits


def print_bus_load(messages, bitrate: float = 1e6) -> None:
    """Bus load at 1 Mbit/s over the last 25 SYNC cycles (steady cyclic exchange)."""
    sync_times = [m.timestamp for m in messages if m.arbitration_id == 0x080 and m.channel == "can0"]
    start = sync_times[max(len(sync_times) - 26, 0)]
    end = sync_times[-1]
    cyclic = [m for m in messages if start <= m.timestamp < end]
    duration = max(end - start, 1e-3)
    for channel in ("can0", "can1"):
        frames = [m for m in cyclic if m.channel == channel]
        nominal = sum(frame_bits(len(m.data), False) for m in frames) / duration / bitrate
        worst = sum(frame_bits(len(m.data), True) for m in frames) / duration / bitrate
        print(f"  {channel}: {len(frames) / duration:.0f} frames/s, bus load {100 * nominal:.1f} % "
              f"({100 * worst:.1f} % with worst-case bit stuffing)")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
