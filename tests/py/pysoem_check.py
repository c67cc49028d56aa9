"""Drives the simulated segment with pysoem (SOEM) and prints what it saw as JSON.

Usage: pysoem_check.py IFACE --large SLAVE:INDEX --foe SLAVE:NAME --od SLAVE[,SLAVE...]

It reports observations only; the Rust test (tests/tests/segment_veth/pysoem.rs) compares them with the
simulator's topology. Any exception ends the script with a non-zero exit code.
"""

import argparse
import json
import sys
import time

import pysoem


def pair(text):
    slave, rest = text.split(":", 1)
    return int(slave), rest


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("iface")
    parser.add_argument("--large", type=pair, required=True, help="SLAVE:INDEX of a large object")
    parser.add_argument("--foe", type=pair, required=True, help="SLAVE:FILENAME to write and read")
    parser.add_argument("--od", required=True, help="comma-separated slaves to list the OD of")
    args = parser.parse_args()
    report = {}

    master = pysoem.Master()
    master.open(args.iface)
    try:
        report["slave_count"] = master.config_init()
        slaves = master.slaves
        report["slaves"] = [
            {"name": s.name, "vendor": s.man, "product": s.id, "revision": s.rev}
            for s in slaves
        ]

        # SDO read of the identity object on every slave that answers SDOs, as listed in --od.
        od_slaves = [int(p) for p in args.od.split(",")]
        report["identity"] = {}
        for p in od_slaves:
            s = slaves[p]
            report["identity"][str(p)] = [
                int.from_bytes(s.sdo_read(0x1018, sub), "little") for sub in (1, 2, 3, 4)
            ]

        # The large object: read it, write a pattern of the same length, read it back.
        large_slave, large_index = args.large[0], int(args.large[1], 0)
        s = slaves[large_slave]
        before = s.sdo_read(large_index, 0, 65536)
        written = bytes((i * 7 + 3) % 256 for i in range(len(before)))
        s.sdo_write(large_index, 0, written)
        after = s.sdo_read(large_index, 0, 65536)
        report["large"] = {
            "before": before.hex(),
            "written": written.hex(),
            "read_back": after.hex(),
        }

        # The object list (SDO Information: OD list, object and entry descriptions).
        report["od"] = {}
        for p in od_slaves:
            report["od"][str(p)] = [
                {
                    "index": obj.index,
                    "name": obj.name.decode(errors="replace") if isinstance(obj.name, bytes) else obj.name,
                    "object_code": obj.object_code,
                    "entries": len(obj.entries),
                }
                for obj in slaves[p].od
            ]

        # FoE: write a file, read it back (in PREOP).
        foe_slave, foe_name = args.foe
        content = bytes((i * 13 + 5) % 256 for i in range(700))
        slaves[foe_slave].foe_write(foe_name, 0, content)
        back = slaves[foe_slave].foe_read(foe_name, 0, 4096)
        report["foe"] = {"written": content.hex(), "read_back": back.hex()}

        # Process data: map, SAFEOP, then OP with the cycle running.
        report["iomap_size"] = master.config_map()
        report["pd_sizes"] = [
            {"inputs": len(s.input), "outputs": len(s.output)} for s in slaves
        ]
        report["safeop"] = master.state_check(pysoem.SAFEOP_STATE, 50000)
        master.send_processdata()
        master.receive_processdata(2000)
        master.state = pysoem.OP_STATE
        master.write_state()
        reached = 0
        for _ in range(400):
            master.send_processdata()
            master.receive_processdata(2000)
            reached = master.state_check(pysoem.OP_STATE, 5000)
            if reached == pysoem.OP_STATE:
                break
        report["op"] = reached
        master.read_state()
        report["states"] = [s.state for s in slaves]
        wkc = 0
        for _ in range(10):
            master.send_processdata()
            wkc = master.receive_processdata(2000)
        report["wkc"] = wkc
        report["expected_wkc"] = master.expected_wkc
        # Back to INIT, as a master does when it ends.
        master.state = pysoem.INIT_STATE
        master.write_state()
    finally:
        master.close()
    json.dump(report, sys.stdout)
    print()


if __name__ == "__main__":
    main()
