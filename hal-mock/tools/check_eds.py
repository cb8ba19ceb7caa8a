#!/usr/bin/env python3
"""Checks the drive's EDS with python-canopen and the master's SDO script against it.

Usage: check_eds.py EDS LOG

The EDS (hal-mock/eds/cia402_servo.eds) must parse with canopen.import_od. Every expedited
SDO transfer the master sent in the candump LOG (the SIL bring-up) must address an object
of the EDS: uploads readable, downloads writable, of the object's size, within its type's
range and limits. The speed limit the master wrote must be the same joint speed in both
units the profile defines: 0x6080 in motor rpm (through the gear ratio 0x6091) and 0x607F
in velocity units (increments/s, through the encoder resolution 0x608F).
"""
import math
import struct
import sys

import can
import canopen

SIZES = {
    canopen.objectdictionary.BOOLEAN: 1,
    canopen.objectdictionary.INTEGER8: 1,
    canopen.objectdictionary.INTEGER16: 2,
    canopen.objectdictionary.INTEGER32: 4,
    canopen.objectdictionary.UNSIGNED8: 1,
    canopen.objectdictionary.UNSIGNED16: 2,
    canopen.objectdictionary.UNSIGNED32: 4,
}


def variable(od, index, sub):
    if index not in od:
        return None
    obj = od[index]
    if isinstance(obj, canopen.objectdictionary.ODVariable):
        return obj if sub == 0 else None
    return obj[sub] if sub in obj else None


def main(eds_path: str, log_path: str) -> int:
    od = canopen.import_od(eds_path, node_id=1)
    for index in (0x1000, 0x6040, 0x6041, 0x6060, 0x6064, 0x607A, 0x6080, 0x607F):
        assert index in od, f"EDS lacks {index:#06x}"
    assert od[0x1000].default & 0xFFFF == 402 and (od[0x1000].default >> 16) & 0xFF == 0x02, \
        "device type is not a CiA 402 servo drive"
    gear = od[0x6091][1].default / od[0x6091][2].default
    increments_per_rev = od[0x608F][1].default / od[0x608F][2].default * gear
    print(f"{eds_path}: {len(od)} objects, gear {gear:g}:1, "
          f"{increments_per_rev:.0f} increments per output revolution")

    uploads = downloads = 0
    written = {}
    for m in can.CanutilsLogReader(log_path):
        cob, data = m.arbitration_id, bytes(m.data)
        if not 0x601 <= cob <= 0x67F or len(data) != 8:
            continue
        node = cob - 0x600
        ccs = data[0] >> 5
        index, sub = struct.unpack_from("<HB", data, 1)
        where = f"node {node}: {index:#06x}:{sub}"
        if ccs == 4:  # abort from the client
            continue
        var = variable(od, index, sub)
        assert var is not None, f"{where} is not in the EDS"
        if ccs == 2:
            uploads += 1
            assert var.readable, f"{where} is not readable ({var.access_type})"
        elif ccs == 1:
            downloads += 1
            assert data[0] & 0x02, f"{where}: not an expedited download"
            size = 4 - ((data[0] >> 2) & 3) if data[0] & 0x01 else 4
            assert var.writable, f"{where} ({var.name}) is {var.access_type}"
            assert SIZES[var.data_type] == size, \
                f"{where} ({var.name}): {size} bytes written, the object has {SIZES[var.data_type]}"
            value = var.decode_raw(data[4:4 + size])
            if var.min is not None:
                assert value >= var.min, f"{where} ({var.name}) = {value} below {var.min}"
            if var.max is not None:
                assert value <= var.max, f"{where} ({var.name}) = {value} above {var.max}"
            written[(node, index, sub)] = value
    assert uploads and downloads, "no SDO traffic in the log"
    nodes = sorted({n for n, _, _ in written})
    assert nodes == list(range(1, 19)), f"SDO downloads for nodes {nodes}"
    for node in nodes:
        for index in (0x6080, 0x607F):
            assert (node, index, 0) in written, f"node {node}: no speed limit written to {index:#06x}"
        rpm = written[(node, 0x6080, 0)]
        from_rpm = rpm * 2 * math.pi / 60 / gear
        from_units = written[(node, 0x607F, 0)] * 2 * math.pi / increments_per_rev
        assert abs(from_rpm - from_units) < 0.01 * from_units, \
            f"node {node}: 0x6080 = {rpm} rpm is {from_rpm:.3f} rad/s, 0x607F is {from_units:.3f} rad/s"
    print(f"{log_path}: {uploads} SDO uploads and {downloads} downloads match the EDS; "
          f"speed limit {from_units:.2f} rad/s = {rpm} motor rpm")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
