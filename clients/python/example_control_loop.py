#!/usr/bin/env python3
"""A control loop on ecatd's cycle: owns the outputs and, every cycle, mirrors the EL1008's
eight inputs (slave 2, 0x6000:1..8) to the EL2008's eight outputs (slave 1, 0x7000:1..8).
Prints the cycle count every second.

    python3 example_control_loop.py [--socket PATH] [--cycles N]
"""

import argparse
import sys
import time

import ecat_app

CHANNELS = range(1, 9)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--socket", help="ecatd's application socket "
                        "(default: $ECAT_APP_SOCKET, else /run/ecatd/app.sock)")
    parser.add_argument("--cycles", type=int, default=0,
                        help="stop after this many cycles (default: run until Ctrl-C)")
    args = parser.parse_args()

    try:
        app = ecat_app.connect(args.socket)
    except ecat_app.Error as err:
        sys.exit("example: %s" % err)
    with app:
        print("attached: generation %d, %d entries, period %.3f ms"
              % (app.generation, len(app.entries), app.period * 1e3), flush=True)
        try:
            for channel in CHANNELS:  # fail early if the layout lacks a terminal
                app.entry(2, 0x6000, channel)
                app.entry(1, 0x7000, channel)
            app.claim()
        except ecat_app.Error as err:
            sys.exit("example: %s" % err)

        done = 0
        last_print = time.monotonic()
        try:
            while args.cycles <= 0 or done < args.cycles:
                try:
                    cycle = app.wait(timeout=1.0)
                except ecat_app.Timeout:
                    print("example: no cycle within 1 s", file=sys.stderr)
                    continue
                except ecat_app.Watchdog as err:
                    # The outputs were taken back (we were too slow): own them again.
                    print("example: %s" % err, file=sys.stderr)
                    app.claim()
                    continue
                # LayoutChanged, Closed: a real program would attach again; we stop.
                for channel in CHANNELS:
                    app.write(1, 0x7000, channel, app.read(2, 0x6000, channel))
                app.commit()
                done += 1
                if time.monotonic() - last_print >= 1.0:
                    last_print = time.monotonic()
                    print("cycle %d, %d cycles mirrored" % (cycle, done), flush=True)
        except KeyboardInterrupt:
            pass
        except ecat_app.Error as err:
            sys.exit("example: %s" % err)
        finally:
            print("cycle %d, %d cycles mirrored" % (app.cycle, done), flush=True)
        app.release()


if __name__ == "__main__":
    main()
