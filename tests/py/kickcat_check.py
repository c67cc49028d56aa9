"""Initialises the simulated segment with KickCAT and reads SDOs; prints JSON.

Usage: kickcat_check.py IFACE --sdo SLAVE[,SLAVE...]

For every listed slave it reads the identity object 0x1018 entry by entry (expedited
uploads), as one complete-access upload, and the device name 0x1008 (a normal upload).
Then it maps the process data and takes the bus to SAFE_OP and OP with the cycle running.
It reports observations only; tests/tests/segment_veth/kickcat.rs compares them with the topology.
"""

import argparse
import json
import sys

import kickcat

# The link timeout the simulator test rig uses (the brief: 20 ms).
LINK_TIMEOUT_S = 0.020
SDO_TIMEOUT_S = 1.0
STATE_TIMEOUT_S = 1.0


# KickCAT's init gives up on the first frame that misses the 20 ms link timeout (its
# EEPROM wait turns any link error into "Timeout"), which a loaded CI machine running tests
# in parallel can cause. Each attempt starts over with a fresh socket; the report says how
# many it took, and three failures in a row fail the test.
INIT_ATTEMPTS = 3


def init_bus(iface):
    for attempt in range(1, INIT_ATTEMPTS + 1):
        link = kickcat.create_link(iface, "")
        link.set_timeout(LINK_TIMEOUT_S)
        bus = kickcat.Bus(link)
        try:
            bus.init(0.1)
            return bus, attempt
        except RuntimeError as error:
            print(f"kickcat init attempt {attempt} failed: {error}", file=sys.stderr)
            if attempt == INIT_ATTEMPTS:
                raise
            del bus, link


def state_name(state):
    return getattr(state, "name", str(state).split(".")[-1])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("iface")
    parser.add_argument("--sdo", required=True, help="comma-separated slaves to read SDOs from")
    args = parser.parse_args()

    bus, attempts = init_bus(args.iface)
    slaves = bus.slaves()
    report = {
        "init_attempts": attempts,
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

    bus.create_mapping()
    report["pd_sizes"] = [
        {"inputs": s.input_size, "outputs": s.output_size} for s in slaves
    ]
    bus.request_state(kickcat.State.SAFE_OP)
    bus.wait_for_state(kickcat.State.SAFE_OP, STATE_TIMEOUT_S)
    bus.process_data()
    bus.request_state(kickcat.State.OPERATIONAL)
    bus.wait_for_state(kickcat.State.OPERATIONAL, STATE_TIMEOUT_S, lambda: bus.process_data())
    report["states"] = [state_name(bus.get_state(s)) for s in slaves]
    json.dump(report, sys.stdout)
    print()


if __name__ == "__main__":
    main()
