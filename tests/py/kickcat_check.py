"""Initialises the simulated segment with KickCAT and reads SDOs; prints JSON.

Usage: kickcat_check.py IFACE --sdo SLAVE[,SLAVE...]

For every listed slave it reads the identity object 0x1018 entry by entry (expedited
uploads), as one complete-access upload, and the device name 0x1008 (a normal upload).
It reports observations only; tests/tests/kickcat.rs compares them with the topology.
"""

import argparse
import json
import sys

import kickcat

# The link timeout the simulator test rig uses (the brief: 20 ms).
LINK_TIMEOUT_S = 0.020
SDO_TIMEOUT_S = 1.0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("iface")
    parser.add_argument("--sdo", required=True, help="comma-separated slaves to read SDOs from")
    args = parser.parse_args()

    link = kickcat.create_link(args.iface, "")
    link.set_timeout(LINK_TIMEOUT_S)
    bus = kickcat.Bus(link)
    bus.init(0.1)
    slaves = bus.slaves()
    report = {
        "slave_count": len(slaves),
        "addresses": [s.address for s in slaves],
        "identity": {},
        "identity_complete": {},
        "name": {},
    }
    for p in (int(x) for x in args.sdo.split(",")):
        s = slaves[p]
        report["identity"][str(p)] = [
            int.from_bytes(
                bus.read_sdo(s, 0x1018, sub, kickcat.Access.PARTIAL, 4, SDO_TIMEOUT_S), "little"
            )
            for sub in (1, 2, 3, 4)
        ]
        report["identity_complete"][str(p)] = bus.read_sdo(
            s, 0x1018, 0, kickcat.Access.COMPLETE, 64, SDO_TIMEOUT_S
        ).hex()
        report["name"][str(p)] = bus.read_sdo(
            s, 0x1008, 0, kickcat.Access.PARTIAL, 64, SDO_TIMEOUT_S
        ).decode(errors="replace")
    json.dump(report, sys.stdout)
    print()


if __name__ == "__main__":
    main()
