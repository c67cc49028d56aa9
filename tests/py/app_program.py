"""A control program for the application-interface tests, on the Python client (ecat_app):
the twin of tests/src/bin/app_program.rs (same command line, same scenarios, same JSON
lines on stdout), so one test body in tests/tests/server/app.rs checks all three libraries.

``app_program.py SOCKET SCENARIO [ARG]``:

- ``drive``: claims, takes the drive (slave 0) through controlword 6, 7, 15 until the
  statusword says "operation enabled", sets target position 123456 and waits until the
  actual position reads it back;
- ``mirror``: claims, writes eight patterns to the DO8 (slave 1, 0x7000:01..08) and counts
  the cycles until the DI8 (slave 2, 0x6000:01..08) reads each back;
- ``hold``: claims (or reports the refusal) and commits every cycle until killed;
- ``monitor N``: read-only, reports the cycle numbers of N waits;
- ``soak SECONDS``: claims and commits every cycle for that long, counting the cycles it
  missed and the commits the frames did not carry;
- ``layout``: waits until the layout changes;
- ``bench SECONDS``: the loop of the ``app_cycle`` benchmark (see the Rust program):
  every cycle reads the DI8, writes the DO8 (low nibble: the commit's tag, high nibble:
  the DI8's high nibble plus one) and commits; reports the wake-up latency, the commits
  the next frame carried, those a later one carried, those no frame carried, those whose
  next cycle the program missed, and the missed cycles.

On an error it prints ``{"error": "<message>"}`` (the message worded as the Rust client's
Display of that error) and exits 1. Standard library only; run with
PYTHONPATH=clients/python.
"""

import collections
import json
import re
import signal
import sys
import time

import ecat_app

#: Timeout of every wait (seconds), as WAIT in the Rust program.
WAIT = 2.0
#: Timeout of the waits in `layout`.
LAYOUT_WAIT = 30.0


class ProgramError(Exception):
    """An error this program finds itself (the Rust program's Error::Protocol): its message
    is printed as is."""


def emit(obj):
    """One result line, flushed at once (the test reads lines while the program runs)."""
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def message(err):
    """The message of a library error, worded as the Rust client's Display of it."""
    if isinstance(err, ecat_app.ProtocolError):
        return "protocol error: %s" % err
    return str(err)


def protocol(what):
    """The Rust program's Error::Protocol(what)."""
    return ProgramError("protocol error: %s" % what)


def read(app, entry):
    """The entry's value in the last cycle (ecat_app reads by slave, index, subindex)."""
    return app.read(entry.slave, entry.index, entry.subindex)


def write(app, entry, value):
    app.write(entry.slave, entry.index, entry.subindex, value)


def parse_u64(text):
    """As Rust's ``str::parse::<u64>().ok()``: an optional '+' and ASCII digits, at most
    2^64 - 1; None otherwise."""
    if text is None or not re.fullmatch(r"\+?[0-9]+", text, flags=re.ASCII):
        return None
    value = int(text)
    return value if value < 1 << 64 else None


def main(argv):
    # As a Rust program: Ctrl-C ends it by the signal, without a traceback.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    if len(argv) < 3:
        print("usage: app_program SOCKET SCENARIO [ARG]", file=sys.stderr)
        return 2
    socket_path, scenario = argv[1], argv[2]
    arg = parse_u64(argv[3] if len(argv) > 3 else None)
    scenarios = {
        "drive": lambda: drive(socket_path),
        "mirror": lambda: mirror(socket_path),
        "hold": lambda: hold(socket_path),
        "monitor": lambda: monitor(socket_path, 100 if arg is None else arg),
        "soak": lambda: soak(socket_path, 60 if arg is None else arg),
        "layout": lambda: layout(socket_path),
        "bench": lambda: bench(socket_path, 10 if arg is None else arg),
    }
    run = scenarios.get(scenario)
    if run is None:
        print("unknown scenario %s" % scenario, file=sys.stderr)
        return 2
    try:
        run()
    except ProgramError as err:
        emit({"error": str(err)})
        return 1
    except ecat_app.Error as err:
        emit({"error": message(err)})
        return 1
    except OSError as err:  # a kernel call the library did not wrap (Rust: Error::Io)
        emit({"error": str(err)})
        return 1
    return 0


def drive(socket_path):
    app = ecat_app.connect(socket_path, read_only=False)
    control = app.entry(0, 0x6040, 0)
    status = app.entry(0, 0x6041, 0)
    target = app.entry(0, 0x607A, 0)
    actual = app.entry(0, 0x6064, 0)
    app.claim()
    start = app.wait(WAIT)
    for command, state in ((6, 0x21), (7, 0x23), (15, 0x27)):
        write(app, control, command)
        app.commit()
        deadline = app.cycle + 100
        while (read(app, status) & 0x6F) != state:
            if app.wait(WAIT) > deadline:
                raise protocol("statusword %#06x after controlword %d"
                               % (read(app, status), command))
            app.commit()
    write(app, target, 123456)
    app.commit()
    while read(app, actual) != 123456:
        app.wait(WAIT)
        app.commit()
    emit({
        "statusword": read(app, status),
        "actual": read(app, actual),
        "cycles": app.cycle - start,
    })


def mirror(socket_path):
    app = ecat_app.connect(socket_path, read_only=False)
    outputs = [app.entry(1, 0x7000, ch) for ch in range(1, 9)]
    inputs = [app.entry(2, 0x6000, ch) for ch in range(1, 9)]
    app.claim()
    app.wait(WAIT)
    worst = 0
    for pattern in (0x01, 0x80, 0x55, 0xAA, 0xFF, 0x00, 0x0F, 0xF0):
        for bit, output in enumerate(outputs):
            write(app, output, (pattern >> bit) & 1)
        app.commit()
        committed = app.cycle
        while True:
            cycle = app.wait(WAIT)
            seen = 0
            for bit, input_ in enumerate(inputs):
                seen |= (read(app, input_) & 1) << bit
            if seen == pattern:
                worst = max(worst, cycle - committed)
                break
            if cycle - committed > 50:
                raise protocol("DI8 reads %#04x, DO8 was given %#04x" % (seen, pattern))
            app.commit()
    emit({"patterns": 8, "worst_cycles": worst})


def hold(socket_path):
    app = ecat_app.connect(socket_path, read_only=False)
    outputs = [app.entry(1, 0x7000, channel) for channel in range(1, 9)]
    try:
        app.claim()
    except ecat_app.Refused as refused:
        emit({"claimed": False, "reason": refused.reason})
        return
    emit({"claimed": True})
    # The DO8 at exactly 0x01, told apart from any safe value the tests configure.
    for channel, output in enumerate(outputs):
        write(app, output, 1 if channel == 0 else 0)
    while True:
        app.wait(WAIT)
        app.commit()


def monitor(socket_path, waits):
    app = ecat_app.connect(socket_path, read_only=True)
    try:
        app.claim()
        refused = False
    except ecat_app.Refused:
        refused = True
    except ecat_app.Error:
        refused = False  # only a refusal counts, as matches!(.., Err(Error::Refused(_)))
    cycles = []
    for _ in range(waits):
        cycles.append(app.wait(WAIT))
    emit({
        "claim_refused": refused,
        "first": cycles[0] if cycles else 0,
        "last": cycles[-1] if cycles else 0,
        "waits": len(cycles),
    })


def soak(socket_path, seconds):
    app = ecat_app.connect(socket_path, read_only=False)
    output = app.entry(1, 0x7000, 1)
    app.claim()
    end = time.monotonic() + seconds
    first = app.wait(WAIT)
    last, missed, not_carried, commits = first, 0, 0, 0
    while time.monotonic() < end:
        cycle = app.wait(WAIT)
        missed += cycle - last - 1
        last = cycle
        # The commit of the last cycle went out in this one's frame, unless it was late.
        if commits > 0 and app.applied != commits:
            not_carried += 1
        write(app, output, cycle & 1)
        app.commit()
        commits += 1
    # The last commit goes out with the next frame at the latest.
    app.wait(WAIT)
    app.wait(WAIT)
    emit({
        "cycles": last - first,
        "missed": missed,
        "not_carried": not_carried,
        "commits": commits,
        "carried": app.applied,
        # app.period is in seconds (the header's nanoseconds / 1e9): exact back to
        # nanoseconds below 2^51 ns.
        "period_ns": round(app.period * 1e9),
    })


def layout(socket_path):
    app = ecat_app.connect(socket_path, read_only=True)
    generation = app.generation
    emit({"attached": generation})
    while True:
        try:
            app.wait(LAYOUT_WAIT)
        except ecat_app.LayoutChanged as changed:
            emit({"layout_changed": changed.generation, "was": generation})
            return


def quantile(samples, q):
    """The sample at quantile ``q`` of the sorted ``samples`` (0 when there are none)."""
    if not samples:
        return 0
    return samples[int((len(samples) - 1) * q)]


def bench(socket_path, seconds):
    app = ecat_app.connect(socket_path, read_only=False)
    outputs = [app.entry(1, 0x7000, ch) for ch in range(1, 9)]
    inputs = [app.entry(2, 0x6000, ch) for ch in range(1, 9)]
    app.claim()
    period_ns = max(1, round(app.period * 1e9))
    clock = time.clock_gettime_ns
    monotonic = time.CLOCK_MONOTONIC
    wakes = []
    pending = collections.deque()  # (commit number, cycle it was computed in)
    next_frame = later = after_miss = replaced = 0
    missed = commits = unstamped = 0
    first = app.wait(WAIT)
    last = first
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        cycle = app.wait(WAIT)
        now = clock(monotonic)
        published = app.published_ns
        if published:
            wakes.append(now - published)
        else:
            unstamped += 1
        missed += cycle - last - 1
        seen = 0
        for bit, input_ in enumerate(inputs):
            seen |= (read(app, input_) & 1) << bit
        # The commit this cycle's frame carried: its tag is on the DI8's low nibble (as in
        # the Rust program).
        tag = seen & 0xF
        for at, (number, made) in enumerate(pending):
            if number & 0xF == tag:
                replaced += at
                if last != made:
                    later += 1
                elif cycle == made + 1:
                    next_frame += 1
                else:
                    after_miss += 1
                for _ in range(at + 1):
                    pending.popleft()
                break
        last = cycle
        commits += 1
        value = ((((seen >> 4) + 1) & 0xF) << 4) | (commits & 0xF)
        for bit, output in enumerate(outputs):
            write(app, output, (value >> bit) & 1)
        app.commit()
        pending.append((commits, cycle))
        if len(pending) > 8:
            # Eight commits without one on the wire: the oldest will never be told apart.
            pending.popleft()
            replaced += 1
    wakes.sort()
    emit({
        "client": "python",
        "period_ns": period_ns,
        "seconds": seconds,
        "cycles": last - first,
        "waits": len(wakes) + unstamped,
        "missed": missed,
        "commits": commits,
        "next_frame": next_frame,
        "later": later,
        "replaced": replaced,
        "after_miss": after_miss,
        "unseen": len(pending),
        "unstamped": unstamped,
        "wake_p50_ns": quantile(wakes, 0.50),
        "wake_p99_ns": quantile(wakes, 0.99),
        "wake_max_ns": wakes[-1] if wakes else 0,
    })


if __name__ == "__main__":
    sys.exit(main(sys.argv))
