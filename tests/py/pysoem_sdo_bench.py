"""Times pysoem's sdo_read of 0x1018:01 on one slave; prints percentiles as JSON.

Usage: pysoem_sdo_bench.py IFACE --slave N --count K

The comparison row of tests/benches/mailbox_veth.rs: the same simulator, the same object,
SOEM's blocking mailbox path. The slaves are left in PREOP (config_init).
"""

import argparse
import json
import sys
import time

import pysoem


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("iface")
    parser.add_argument("--slave", type=int, default=0)
    parser.add_argument("--count", type=int, default=2000)
    args = parser.parse_args()
    master = pysoem.Master()
    master.open(args.iface)
    try:
        master.config_init()
        slave = master.slaves[args.slave]
        # Warm-up, then the timed reads.
        for _ in range(args.count // 10):
            slave.sdo_read(0x1018, 1)
        samples = []
        start = time.perf_counter()
        for _ in range(args.count):
            t = time.perf_counter()
            slave.sdo_read(0x1018, 1)
            samples.append(time.perf_counter() - t)
        elapsed = time.perf_counter() - start
    finally:
        master.close()
    samples.sort()
    at = lambda q: samples[int((len(samples) - 1) * q)] * 1e6
    json.dump(
        {"p50_us": at(0.50), "p99_us": at(0.99), "per_second": args.count / elapsed},
        sys.stdout,
    )
    print()


if __name__ == "__main__":
    main()
