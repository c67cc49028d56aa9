"""Drives a ring (cable redundancy) with pysoem (SOEM's redundant mode) and reports as JSON.

Usage: pysoem_ring.py PRIMARY BACKUP --sdo SLAVE [--cycles N]

Brings every slave to OP, reads 0x1018:01 of SLAVE, then keeps the process-data cycle
running while the Rust test (tests/tests/segment_veth/redundancy_pysoem.rs) changes the
wiring. It talks to the test over its standard streams, one line each way per step:

- it prints a JSON line with "step": "op" once every slave is in OP, then cycles until a
  line arrives on stdin ("broken": the test cut a cable);
- it cycles N more cycles, reads the SDO again, prints "step": "broken", and cycles until
  the next line ("healed");
- it cycles N more cycles, prints "step": "healed", takes the slaves to INIT and ends.

Each report has the DL status (0x0110) of every slave, read over the ring. Every report counts the cycles whose working counter was not the expected one since the
last report, and the working counters of its last cycles. It reports observations only;
the Rust test judges them. A cycle loop that waits for a line gives up after a bound (the
test would have failed by then) and the script exits non-zero on any exception.
"""

import argparse
import json
import select
import sys
import time

import pysoem

# Upper bound on the cycles spent waiting for the test's next line (about a minute).
WAIT_CYCLES = 60000
# Pacing of the cycle (seconds): a 1 ms cycle, not a synchronisation.
PERIOD = 0.001


class Cycle:
    """The process-data cycle and its working-counter record."""

    def __init__(self, master):
        self.master = master
        self.bad = 0
        self.cycles = 0
        self.last = []

    def once(self):
        self.master.send_processdata()
        wkc = self.master.receive_processdata(2000)
        self.cycles += 1
        if wkc != self.master.expected_wkc:
            self.bad += 1
        self.last = (self.last + [wkc])[-20:]
        time.sleep(PERIOD)

    def run(self, count):
        for _ in range(count):
            self.once()

    def until_line(self):
        """Cycles until a line arrives on stdin; returns it ("" on a bound or EOF)."""
        for _ in range(WAIT_CYCLES):
            self.once()
            ready, _, _ = select.select([sys.stdin], [], [], 0)
            if ready:
                return sys.stdin.readline().strip()
        return ""

    def report(self, step, **extra):
        """Prints one step's report and starts a new count."""
        self.master.read_state()
        line = {
            "step": step,
            "cycles": self.cycles,
            "bad_cycles": self.bad,
            "last_wkc": self.last,
            "expected_wkc": self.master.expected_wkc,
            "states": [s.state for s in self.master.slaves],
        }
        line.update(extra)
        print(json.dumps(line), flush=True)
        self.bad = 0
        self.cycles = 0


def vendor(slave):
    return int.from_bytes(slave.sdo_read(0x1018, 1), "little")


def dl_status(slaves):
    """DL status 0x0110 of every slave (which ports have a link), read with FPRD."""
    return [int.from_bytes(s._fprd(0x0110, 2, 20000), "little") for s in slaves]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("primary")
    parser.add_argument("backup")
    parser.add_argument("--sdo", type=int, required=True, help="a CoE slave to read 0x1018:01 of")
    parser.add_argument("--cycles", type=int, default=300, help="cycles after each change")
    args = parser.parse_args()

    master = pysoem.Master()
    master.open(args.primary, args.backup)
    try:
        found = master.config_init()
        slaves = master.slaves
        identity = [{"name": s.name, "vendor": s.man, "product": s.id} for s in slaves]
        vendor_before = vendor(slaves[args.sdo])
        iomap = master.config_map()
        safeop = master.state_check(pysoem.SAFEOP_STATE, 50000)
        cycle = Cycle(master)
        cycle.once()
        master.state = pysoem.OP_STATE
        master.write_state()
        reached = 0
        for _ in range(400):
            cycle.once()
            reached = master.state_check(pysoem.OP_STATE, 5000)
            if reached == pysoem.OP_STATE:
                break
        cycle.run(args.cycles)
        cycle.report(
            "op",
            slave_count=found,
            slaves=identity,
            iomap_size=iomap,
            safeop=safeop,
            op=reached,
            vendor=vendor_before,
            dl_status=dl_status(slaves),
        )

        got = cycle.until_line()
        if got != "broken":
            raise RuntimeError(f"expected 'broken', got {got!r}")
        cycle.run(args.cycles)
        vendor_after = vendor(slaves[args.sdo])
        cycle.run(args.cycles)
        cycle.report("broken", vendor=vendor_after, dl_status=dl_status(slaves))

        got = cycle.until_line()
        if got != "healed":
            raise RuntimeError(f"expected 'healed', got {got!r}")
        cycle.run(args.cycles)
        cycle.report("healed", vendor=vendor(slaves[args.sdo]), dl_status=dl_status(slaves))

        master.state = pysoem.INIT_STATE
        master.write_state()
    finally:
        master.close()


if __name__ == "__main__":
    main()
