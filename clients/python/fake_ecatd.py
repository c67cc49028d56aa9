"""A fake ecatd for testing application clients without a bus or the daemon.

It serves the application protocol of docs/application.md on a Unix socket in a temporary
directory: it lays out an image region and, per claim, a commit region (memfds passed with
SCM_RIGHTS), publishes cycles with the seqlock writer's order, wakes each attachment's
eventfd, takes the owner's commits before each "frame" like ecatd, and sends event lines on
demand. The offsets are written out here from the document, independently of ecat_app.py, so
the tests check the client against the document rather than against itself.

Used by test_ecat_app.py in process, and by the C test client through
:meth:`FakeEcatd.command` (one command line from the child, one reply line back).

Run on its own (``python3 fake_ecatd.py --socket /tmp/app.sock``) it serves the DI8/DO8
layout of the examples at 100 Hz, with a counting pattern on the inputs.
"""

import array
import collections
import mmap
import os
import shutil
import socket
import struct
import tempfile
import threading
import time

PAGE = 4096

FakeEntry = collections.namedtuple(
    "FakeEntry",
    "slave station pdo index subindex direction data_type bit_offset bit_length name")

# The layout of the self-tests: a signed INTEGER16 at an odd bit offset, an UNSIGNED32
# input, a 1-bit BOOLEAN output, an INTEGER8 output and a REAL32 input; 16 bytes.
TEST_IMAGE_LEN = 16
TEST_ENTRIES = [
    FakeEntry(2, 0x1002, 0x1A00, 0x6000, 0x01, "in", 0x0003, 3, 16, "Analog input"),
    FakeEntry(2, 0x1002, 0x1A01, 0x6010, 0x01, "in", 0x0007, 24, 32, "Counter value"),
    FakeEntry(1, 0x1001, 0x1600, 0x7000, 0x01, "out", 0x0001, 69, 1, "Output 1"),
    FakeEntry(1, 0x1001, 0x1601, 0x7010, 0x02, "out", 0x0002, 72, 8, "Setpoint"),
    FakeEntry(2, 0x1002, 0x1A02, 0x6020, 0x11, "in", 0x0008, 96, 32, "Temperature"),
]
# What "publish" puts into the test layout: inputs as received, outputs as sent.
TEST_INPUTS = {0: -2, 1: 0xDEADBEEF, 4: struct.unpack("<I", struct.pack("<f", 21.5))[0]}
TEST_SENT = {2: 1, 3: -5}

# The examples' layout: an EL2008 (slave 1, 8 outputs 0x7000:1..8 in byte 0) and an EL1008
# (slave 2, 8 inputs 0x6000:1..8 in byte 1).
IO_IMAGE_LEN = 2
IO_ENTRIES = (
    [FakeEntry(1, 0x1001, 0x1600 + i, 0x7000, i + 1, "out", 0x0001, i, 1, "Output %d" % (i + 1))
     for i in range(8)] +
    [FakeEntry(2, 0x1002, 0x1A00 + i, 0x6000, i + 1, "in", 0x0001, 8 + i, 1, "Input %d" % (i + 1))
     for i in range(8)])


def _r64(n):
    return (n + 63) // 64 * 64


def _pages(n):
    return (n + PAGE - 1) // PAGE * PAGE


def get_bits(image, entry):
    """The raw bits of ``entry`` in ``image`` (bit by bit, as the document defines them)."""
    value = 0
    for i in range(entry.bit_length):
        bit = entry.bit_offset + i
        if image[bit // 8] >> (bit % 8) & 1:
            value |= 1 << i
    return value


def set_bits(image, entry, value):
    """Writes the low bits of ``value`` (two's complement for negatives) into ``image``."""
    value &= (1 << entry.bit_length) - 1
    for i in range(entry.bit_length):
        bit = entry.bit_offset + i
        if value >> i & 1:
            image[bit // 8] |= 1 << (bit % 8)
        else:
            image[bit // 8] &= ~(1 << (bit % 8)) & 0xFF


def signed_bits(image, entry):
    """``get_bits`` sign-extended."""
    raw = get_bits(image, entry)
    if raw >> (entry.bit_length - 1):
        raw -= 1 << entry.bit_length
    return raw


def _memfd(name, length):
    fd = os.memfd_create(name, os.MFD_CLOEXEC)
    os.ftruncate(fd, length)
    return fd


class _Client:
    def __init__(self, conn):
        self.conn = conn
        self.lock = threading.Lock()
        self.events_r = self.events_w = -1
        self.writable = False
        self.hello = False
        pid, uid, _gid = struct.unpack(
            "3i", conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, 12))
        self.pid, self.uid = pid, uid

    def send(self, data, fds=(), split=False):
        with self.lock:
            try:
                if fds:
                    first = data[:3] if split else data
                    self.conn.sendmsg(
                        [first], [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", fds))])
                    if split:
                        time.sleep(0.02)  # the rest as a separate read
                        self.conn.sendall(data[3:])
                else:
                    self.conn.sendall(data)
            except OSError:
                pass

    def wake(self):
        if self.events_w >= 0:
            try:
                os.write(self.events_w, struct.pack("<Q", 1))
            except OSError:
                pass

    def close(self):
        # Both the server thread and disconnect_all() may get here: close each fd once.
        with self.lock:
            fds = {self.events_r, self.events_w} - {-1}
            self.events_r = self.events_w = -1
        for fd in fds:
            os.close(fd)
        try:
            self.conn.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass


class FakeEcatd:
    """One fake ecatd on ``self.path``; close() (or use as a context manager) when done."""

    def __init__(self, entries=TEST_ENTRIES, image_len=TEST_IMAGE_LEN, generation=1,
                 period_ns=1_000_000, initial_commit=0, split_answers=False, path=None):
        self.entries = list(entries)
        self.image_len = image_len
        self.generation = generation
        self.initial_commit = initial_commit
        self.split_answers = split_answers
        #: When set, every CLAIM is refused with this reason.
        self.claim_refusal = None
        self.cycle = 0
        self.applied = 0
        self.owner = None
        self.commit_map = None
        self.inputs = bytearray(image_len)
        self.outputs = bytearray(image_len)  # the outputs each frame sends
        self._taken = 0
        self._lock = threading.RLock()
        self._clients = []
        self._attached = threading.Condition(self._lock)
        self._publisher = None
        self._stop = threading.Event()

        # The image region (docs/application.md, "The image region").
        self.slots = _r64(0x100 + len(self.entries) * 64)
        self.stride = 64 + 2 * _r64(image_len)
        self.region_len = _pages(self.slots + 3 * self.stride)
        self._image_fd = _memfd("fake-ecatd-image", self.region_len)
        self.image = mmap.mmap(self._image_fd, self.region_len)
        m = self.image
        m[0:8] = b"ECATAPP\0"
        struct.pack_into("<IIIIIIIIII", m, 0x008,
                         1,                    # layout version
                         1,                    # flags: LIVE
                         generation,
                         image_len,
                         len(self.entries),
                         64,                   # bytes per entry
                         0x100,                # entry table
                         self.slots,
                         self.stride,
                         3)                    # input slots
        struct.pack_into("<Q", m, 0x030, period_ns)
        struct.pack_into("<I", m, 0x050, 10)  # watchdog
        for i, e in enumerate(self.entries):
            struct.pack_into("<HHHHBBHIH46s", m, 0x100 + 64 * i, e.slave, e.station, e.pdo,
                             e.index, e.subindex, 1 if e.direction == "out" else 0,
                             e.data_type, e.bit_offset, e.bit_length, e.name.encode())

        self._dir = tempfile.mkdtemp(prefix="fake-ecatd-")
        self.path = path or os.path.join(self._dir, "app.sock")
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._listener.bind(self.path)
        self._listener.listen(16)
        self._accepter = threading.Thread(target=self._accept, daemon=True)
        self._accepter.start()

    # -- the cycle --

    def publish(self, inputs=None, sent=None):
        """Publishes the next cycle: takes the owner's new commit (as ecatd before a frame),
        then writes the slot (stamp 0, data, stamp) and the header's cycle, and wakes every
        attachment. ``inputs`` replaces the image received, ``sent`` the outputs before the
        owner's commit is taken. Returns the cycle."""
        with self._lock:
            if inputs is not None:
                self.inputs[:] = inputs
            if sent is not None:
                self.outputs[:] = sent
            self.take_commit()
            self.cycle += 1
            c = self.cycle
            slot = self.slots + (c % 3) * self.stride
            m = self.image
            struct.pack_into("<Q", m, slot, 0)
            struct.pack_into("<HH", m, slot + 8, 3, 3)
            struct.pack_into("<Q", m, slot + 16, time.clock_gettime_ns(time.CLOCK_MONOTONIC))
            m[slot + 64:slot + 64 + self.image_len] = self.inputs
            at = slot + 64 + _r64(self.image_len)
            m[at:at + self.image_len] = self.outputs
            struct.pack_into("<Q", m, slot, c)
            struct.pack_into("<Q", m, 0x038, c)
            for client in self._clients:
                client.wake()
            return c

    def take_commit(self):
        """ecatd's side of "Committing": a new whole commit's output bits go out."""
        with self._lock:
            if self.owner is None or self.commit_map is None:
                return False
            m = self.commit_map
            n = struct.unpack_from("<Q", m, 0x020)[0]
            if n == self._taken:
                return False
            slot = 0x40 + (n % 3) * (64 + _r64(self.image_len))
            if struct.unpack_from("<Q", m, slot)[0] != n:
                return False
            data = bytes(m[slot + 64:slot + 64 + self.image_len])
            if struct.unpack_from("<Q", m, slot)[0] != n:
                return False
            for e in self.entries:
                if e.direction == "out":
                    set_bits(self.outputs, e, get_bits(data, e))
            self._taken = n
            self.applied = n
            struct.pack_into("<Q", self.image, 0x040, n)
            return True

    def test_images(self):
        """(inputs, sent) of the test layout with TEST_INPUTS and TEST_SENT."""
        inputs, sent = bytearray(self.image_len), bytearray(self.image_len)
        for i, v in TEST_INPUTS.items():
            set_bits(inputs, self.entries[i], v)
        for i, v in TEST_SENT.items():
            set_bits(sent, self.entries[i], v)
        return inputs, sent

    def start_publisher(self, period=0.005, inputs=None):
        """Publishes a cycle every ``period`` seconds in a thread; ``inputs(cycle)`` gives
        each cycle's received image."""
        def run():
            while not self._stop.wait(period):
                self.publish(None if inputs is None else inputs(self.cycle + 1))
        self._publisher = threading.Thread(target=run, daemon=True)
        self._publisher.start()

    # -- events --

    def send_all(self, data):
        """Sends raw bytes (e.g. an event line) to every attachment."""
        with self._lock:
            clients = list(self._clients)
        for client in clients:
            client.send(data)

    def watchdog(self):
        """Ends the ownership as the watchdog does and tells the owner."""
        with self._lock:
            owner = self._end_ownership()
        if owner is not None:
            owner.send(b"EVENT watchdog\n")

    def mark_stale(self):
        struct.pack_into("<I", self.image, 0x00C, 2)  # STALE, no longer LIVE

    def disconnect_all(self):
        with self._lock:
            clients, self._clients = self._clients, []
            self._end_ownership()
        for client in clients:
            client.close()

    def wait_attached(self, count, timeout=5.0):
        """Blocks until ``count`` attachments said HELLO."""
        with self._attached:
            return self._attached.wait_for(
                lambda: sum(c.hello for c in self._clients) >= count, timeout)

    # -- the commit region, as the tests see it --

    def commit_number(self):
        return struct.unpack_from("<Q", self.commit_map, 0x020)[0]

    def commit_slot(self, n):
        """(stamp, image) of the slot commit ``n`` goes to."""
        slot = 0x40 + (n % 3) * (64 + _r64(self.image_len))
        stamp = struct.unpack_from("<Q", self.commit_map, slot)[0]
        return stamp, bytes(self.commit_map[slot + 64:slot + 64 + self.image_len])

    # -- a child process's commands (the C test client) --

    def command(self, line):
        """Carries out one command line of a test child; returns the reply line."""
        words = line.split()
        if not words:
            return "fail empty command"
        what = words[0]
        if what == "publish":
            # TEST_SENT seeds the outputs; later frames send what the owner committed.
            inputs, sent = self.test_images()
            self.publish(inputs, sent if self.cycle == 0 else None)
        elif what == "watchdog":
            self.watchdog()
        elif what == "event":
            self.send_all((" ".join(words[1:]) + "\n").encode())
        elif what == "longline":
            self.send_all(b"EVENT " + b"x" * 300 + b"\n")
        elif what == "partial":
            self.send_all(b"EVENT watch")
        elif what == "disconnect":
            self.disconnect_all()
        elif what == "stale":
            self.mark_stale()
        elif what == "attached":
            if not self.wait_attached(int(words[1])):
                return "fail not attached"
        elif what == "commit":
            # "ok <commit> <stamp of its slot> <value of each output entry>..."
            n = self.commit_number()
            stamp, data = self.commit_slot(n)
            values = [str(signed_bits(data, e) if e.data_type in (2, 3, 4) else get_bits(data, e))
                      for e in self.entries if e.direction == "out"]
            return "ok %d %d %s" % (n, stamp, " ".join(values))
        else:
            return "fail unknown command %r" % what
        return "ok"

    # -- the server --

    def _accept(self):
        while True:
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return
            client = _Client(conn)
            with self._lock:
                self._clients.append(client)
            threading.Thread(target=self._serve, args=(client,), daemon=True).start()

    def _serve(self, client):
        buf = b""
        try:
            while True:
                try:
                    data = client.conn.recv(256)
                except OSError:
                    data = b""
                if not data:
                    return
                buf += data
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    if not self._request(client, line.decode("ascii", "replace")):
                        return
                if len(buf) > 256:
                    client.send(b"ERR line too long\n")
                    return
        finally:
            with self._lock:
                if self.owner is client:
                    self._end_ownership()
                if client in self._clients:
                    self._clients.remove(client)
                self._attached.notify_all()
            client.close()
            client.conn.close()

    def _request(self, client, line):
        words = line.split(" ")
        if words[0] == "HELLO" and len(words) == 3 and words[2] in ("ro", "rw"):
            if words[1] != "1":
                client.send(b"ERR unsupported protocol version\n")
                return False
            if hasattr(os, "eventfd"):
                client.events_r = os.eventfd(0, os.EFD_CLOEXEC | os.EFD_NONBLOCK)
                client.events_w = client.events_r
            else:  # Python 3.9: a pipe wakes the same way
                client.events_r, client.events_w = os.pipe2(os.O_CLOEXEC | os.O_NONBLOCK)
            client.writable = words[2] == "rw"
            # A read-only open of the memfd, as ecatd hands it out.
            ro = os.open("/proc/self/fd/%d" % self._image_fd, os.O_RDONLY | os.O_CLOEXEC)
            try:
                client.send(b"OK HELLO %d %d\n" % (self.generation, self.region_len),
                            [ro, client.events_r], split=self.split_answers)
            finally:
                os.close(ro)
            with self._attached:
                client.hello = True
                self._attached.notify_all()
        elif line == "CLAIM":
            with self._lock:
                if not client.writable:
                    client.send(b"ERR read-only attachment\n")
                elif self.claim_refusal is not None:
                    client.send(b"ERR %s\n" % self.claim_refusal.encode())
                elif self.owner is not None and self.owner is not client:
                    client.send(b"ERR owned pid=%d uid=%d\n" % (self.owner.pid, self.owner.uid))
                else:
                    self._grant(client)
        elif line == "RELEASE":
            with self._lock:
                if self.owner is client:
                    self._end_ownership()
            client.send(b"OK RELEASE\n")
        elif line == "PING":
            client.send(b"OK PING\n")
        else:
            client.send(b"ERR unknown request\n")
            return False
        return True

    def _grant(self, client):
        stride = 64 + _r64(self.image_len)
        length = _pages(0x40 + 3 * stride)
        fd = _memfd("fake-ecatd-commit", length)
        try:
            m = mmap.mmap(fd, length)
            m[0:8] = b"ECATOUT\0"
            struct.pack_into("<IIIII", m, 0x008, self.generation, self.image_len, 0x40, stride, 3)
            struct.pack_into("<Q", m, 0x020, self.initial_commit)
            self.commit_map = m
            self._taken = self.initial_commit
            self.owner = client
            struct.pack_into("<II", self.image, 0x048, client.pid, client.uid)
            client.send(b"OK CLAIM %d\n" % length, [fd], split=self.split_answers)
        finally:
            os.close(fd)

    def _end_ownership(self):
        """Safe outputs (all zero) from the next frame; returns the former owner."""
        owner, self.owner = self.owner, None
        if owner is not None:
            for e in self.entries:
                if e.direction == "out":
                    set_bits(self.outputs, e, 0)
            struct.pack_into("<II", self.image, 0x048, 0, 0)
        return owner

    # -- the end --

    def close(self):
        self._stop.set()
        if self._publisher is not None:
            self._publisher.join()
        try:
            self._listener.close()
        except OSError:
            pass
        self.disconnect_all()
        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def main():
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--socket", help="where to listen (default: a temporary directory)")
    parser.add_argument("--rate", type=float, default=100.0, help="cycles per second")
    args = parser.parse_args()
    fake = FakeEcatd(IO_ENTRIES, IO_IMAGE_LEN, period_ns=int(1e9 / args.rate), path=args.socket)
    print("serving on", fake.path, flush=True)
    fake.start_publisher(1.0 / args.rate, inputs=lambda c: bytes([0, (c // 100) & 0xFF]))
    try:
        while True:
            time.sleep(1)
            print("cycle %d applied %d outputs %s" % (fake.cycle, fake.applied,
                                                      fake.outputs.hex()), flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        fake.close()
        if args.socket:
            os.unlink(args.socket)


if __name__ == "__main__":
    main()
