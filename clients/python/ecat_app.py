"""A control program's side of ecatd's application interface, in pure Python.

Attach to ecatd over its Unix socket, follow the cycle through the shared process image,
own the outputs and commit them whole. The protocol and the shared memory layout are the
ones of docs/application.md; this module mirrors the Rust client (clients/rust/src/).

    import ecat_app
    with ecat_app.connect() as app:          # $ECAT_APP_SOCKET or /run/ecatd/app.sock
        app.claim()
        while True:
            app.wait(timeout=1.0)
            app.write(1, 0x7000, 1, app.read(2, 0x6000, 1))
            app.commit()

Only the standard library is used (socket, mmap, struct, select, os).

Memory ordering: Python has no fences. Every 8-byte field is read and written with one
``struct.unpack_from``/``struct.pack_into`` of ``<Q`` (on a little-endian machine CPython
uses its native packer, a fixed 8-byte memcpy that compilers emit as one load or store;
in practice, not by any guarantee), and CPython executes these calls in program order. On
x86-64, which reorders neither stores with stores nor loads with loads, that is the seqlock
of docs/application.md; on other architectures use the C or Rust client for the owner
(docs/application.md, "Safety rules").
"""

import array
import math
import mmap
import os
import select
import socket
import struct
import time

__all__ = [
    "connect", "App", "Entry", "Error", "Refused", "ProtocolError", "Timeout",
    "LayoutChanged", "Watchdog", "Closed", "NoSuchEntry", "NotOutput", "OutOfRange",
    "NotOwner", "SYSTEM_SOCKET", "default_socket", "TYPE_NAMES",
]

# --- docs/application.md, "The protocol" -------------------------------------------------

#: The protocol version this module speaks.
PROTOCOL_VERSION = 1
#: The longest line either side sends or accepts, newline included.
MAX_LINE = 256
#: Descriptors one message carries at most.
MAX_FDS = 4
#: How long a request's answer may take (``wait`` has its own timeout).
ANSWER_TIMEOUT = 5.0

#: The socket ecatd serves as a system service.
SYSTEM_SOCKET = "/run/ecatd/app.sock"

# --- docs/application.md, "Shared memory, byte by byte" ----------------------------------

IMAGE_MAGIC = b"ECATAPP\0"
COMMIT_MAGIC = b"ECATOUT\0"
LAYOUT_VERSION = 1
SLOTS = 3                 # slots in each ring
SLOT_HEADER = 64          # bytes of a slot's stamp and counters before its data
SLOT_PUBLISHED_NS = 16    # u64 in a slot: CLOCK_MONOTONIC ns when ecatd published it
ENTRY_SIZE = 64
ENTRIES_OFFSET = 0x100    # where ecatd puts the entry table
PAGE = 4096

FLAG_LIVE = 1 << 0
FLAG_STALE = 1 << 1

# Image region header.
_I_MAGIC = 0x000
_I_VERSION = 0x008
_I_FLAGS = 0x00C
_I_GENERATION = 0x010
_I_IMAGE_LEN = 0x014
_I_ENTRY_COUNT = 0x018
_I_ENTRY_SIZE = 0x01C
_I_ENTRIES = 0x020
_I_SLOTS = 0x024
_I_SLOT_STRIDE = 0x028
_I_SLOT_COUNT = 0x02C
_I_PERIOD_NS = 0x030
_I_CYCLE = 0x038
_I_APPLIED = 0x040
_I_OWNER_PID = 0x048
_I_OWNER_UID = 0x04C
_I_WATCHDOG = 0x050
_I_TRIPS = 0x054

# Commit region header.
_C_MAGIC = 0x000
_C_GENERATION = 0x008
_C_IMAGE_LEN = 0x00C
_C_SLOTS = 0x010
_C_SLOT_STRIDE = 0x014
_C_SLOT_COUNT = 0x018
_C_COMMIT = 0x020
_C_FIRST_SLOT = 0x040

_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")


def round64(n):
    """``n`` rounded up to a multiple of 64."""
    return (n + 63) // 64 * 64


def image_shape(image_len, entries):
    """(first slot, slot stride, inputs within a slot, outputs within a slot, region bytes)
    of an image region for ``image_len`` bytes and ``entries`` entries."""
    slots = round64(ENTRIES_OFFSET + entries * ENTRY_SIZE)
    stride = SLOT_HEADER + 2 * round64(image_len)
    length = (slots + SLOTS * stride + PAGE - 1) // PAGE * PAGE
    return slots, stride, SLOT_HEADER, SLOT_HEADER + round64(image_len), length


def commit_shape(image_len):
    """(slot stride, region bytes) of a commit region for ``image_len`` bytes."""
    stride = SLOT_HEADER + round64(image_len)
    length = (_C_FIRST_SLOT + SLOTS * stride + PAGE - 1) // PAGE * PAGE
    return stride, length


def default_socket():
    """Where a program attaches when it names no socket: ``$ECAT_APP_SOCKET``, else
    ``/run/ecatd/app.sock``."""
    return os.environ.get("ECAT_APP_SOCKET", SYSTEM_SOCKET)


# --- errors (the Rust client's error.rs) --------------------------------------------------

class Error(Exception):
    """Anything that goes wrong while attached to ecatd."""


class Refused(Error):
    """ecatd refused the request; ``reason`` is its word (e.g. ``owned pid=12 uid=0``)."""

    def __init__(self, reason):
        super().__init__("refused by ecatd: %s" % reason)
        self.reason = reason


class ProtocolError(Error):
    """ecatd sent something this module does not understand, or a region that is not one."""


class Timeout(Error):
    """No cycle completed within the time given."""

    def __init__(self, message="no cycle within the timeout"):
        super().__init__(message)


class LayoutChanged(Error):
    """A new layout generation replaced the one this program attached to: attach again.
    Every further ``wait`` fails the same way."""

    def __init__(self, generation):
        super().__init__("layout changed (generation %d): attach again" % generation)
        self.generation = generation


class Watchdog(Error):
    """The watchdog (or ecatd) took the outputs back; claim again to own them."""

    def __init__(self, message="the outputs were taken back (watchdog): claim again"):
        super().__init__(message)


class Closed(Error):
    """ecatd closed the connection (it stopped, or detached this program). Sticky."""

    def __init__(self, message="ecatd closed the connection"):
        super().__init__(message)


class NoSuchEntry(Error):
    """The layout maps no such entry."""

    def __init__(self, slave, index, subindex):
        super().__init__("slave %d maps no entry 0x%04X:%02X" % (slave, index, subindex))
        self.slave, self.index, self.subindex = slave, index, subindex


class NotOutput(Error):
    """Only output entries can be written."""


class OutOfRange(Error):
    """The value does not fit the entry's type and bits."""


class NotOwner(Error):
    """Commit without owning the outputs."""

    def __init__(self, message="this program does not own the outputs: claim first"):
        super().__init__(message)


# --- entries (the Rust client's entry.rs) -------------------------------------------------

#: CoE data type names (ETG.1000.6 Table 64) by code.
TYPE_NAMES = {
    0x0001: "BOOLEAN", 0x0002: "INTEGER8", 0x0003: "INTEGER16", 0x0004: "INTEGER32",
    0x0005: "UNSIGNED8", 0x0006: "UNSIGNED16", 0x0007: "UNSIGNED32", 0x0008: "REAL32",
    0x0009: "VISIBLE_STRING", 0x000A: "OCTET_STRING", 0x000B: "UNICODE_STRING",
    0x000C: "TIME_OF_DAY", 0x000D: "TIME_DIFFERENCE", 0x000F: "DOMAIN",
    0x0010: "INTEGER24", 0x0011: "REAL64", 0x0012: "INTEGER40", 0x0013: "INTEGER48",
    0x0014: "INTEGER56", 0x0015: "INTEGER64", 0x0016: "UNSIGNED24", 0x0018: "UNSIGNED40",
    0x0019: "UNSIGNED48", 0x001A: "UNSIGNED56", 0x001B: "UNSIGNED64",
}

# Signed CoE integers: INTEGER8..32, INTEGER24, INTEGER40..64 (as Entry::is_signed).
_SIGNED = frozenset((0x0002, 0x0003, 0x0004, 0x0010, 0x0012, 0x0013, 0x0014, 0x0015))
# Floating point types read and written as Python floats, with the bit length they need.
_FLOATS = {0x0008: (32, struct.Struct("<f")), 0x0011: (64, struct.Struct("<d"))}

_NAME_LEN = 46
_ENTRY = struct.Struct("<HHHHBBHIH46s")


class Entry:
    """One mapped object of one slave, with its place in the image (the 64-byte record of
    docs/application.md, "An entry")."""

    __slots__ = ("slave", "station", "pdo", "index", "subindex", "direction", "type_code",
                 "type", "bit_offset", "bit_length", "name", "_float")

    def __init__(self, slave, station, pdo, index, subindex, direction, type_code,
                 bit_offset, bit_length, name):
        self.slave = slave            # ring position
        self.station = station        # station address
        self.pdo = pdo                # the PDO that maps it
        self.index = index
        self.subindex = subindex
        self.direction = direction    # "in" or "out"
        self.type_code = type_code    # CoE type code, 0: not known
        self.type = TYPE_NAMES.get(type_code)
        self.bit_offset = bit_offset  # bit 0 = least significant bit of byte 0
        self.bit_length = bit_length
        self.name = name
        known = _FLOATS.get(type_code)
        # A float type only reads as a float at its own width.
        self._float = known[1] if known and known[0] == bit_length else None

    @classmethod
    def decode(cls, record):
        """The entry a 64-byte record holds; None for a record that is not one (a direction
        other than 0 or 1)."""
        (slave, station, pdo, index, subindex, direction, type_code, bit_offset, bit_length,
         name) = _ENTRY.unpack_from(record)
        if direction not in (0, 1):
            return None
        name = name.split(b"\0", 1)[0].decode("utf-8", "replace")
        return cls(slave, station, pdo, index, subindex, "out" if direction else "in",
                   type_code, bit_offset, bit_length, name)

    @property
    def signed(self):
        """Whether the CoE type is a signed integer."""
        return self.type_code in _SIGNED

    def fits(self, image_len):
        """Whether its bits lie inside an image of ``image_len`` bytes and it is at most 64
        bits (the Rust client refuses a layout with a longer entry the same way)."""
        return self.bit_length <= 64 and self.bit_offset + self.bit_length <= 8 * image_len

    def get(self, image):
        """Its raw bits in ``image`` (little-endian, zero-extended); 0 if it does not fit."""
        if not self.fits(len(image)):
            return 0
        first = self.bit_offset >> 3
        last = (self.bit_offset + self.bit_length + 7) >> 3
        word = int.from_bytes(image[first:last], "little") >> (self.bit_offset & 7)
        return word & ((1 << self.bit_length) - 1)

    def set(self, image, raw):
        """Writes the low ``bit_length`` bits of ``raw`` into the bytearray ``image``,
        leaving every other bit alone; False if it does not fit."""
        if not self.fits(len(image)):
            return False
        first = self.bit_offset >> 3
        last = (self.bit_offset + self.bit_length + 7) >> 3
        shift = self.bit_offset & 7
        mask = ((1 << self.bit_length) - 1) << shift
        word = int.from_bytes(image[first:last], "little")
        word = (word & ~mask) | ((raw << shift) & mask)
        image[first:last] = word.to_bytes(last - first, "little")
        return True

    def value(self, image):
        """Its value in ``image``: a float for REAL32/REAL64, else an int, sign-extended for
        the signed types."""
        raw = self.get(image)
        if self._float is not None:
            return self._float.unpack(raw.to_bytes(self.bit_length // 8, "little"))[0]
        bits = self.bit_length
        if self.signed and bits and raw >> (bits - 1):
            return raw - (1 << bits)
        return raw

    def encode(self, value):
        """The raw bits of ``value`` for this entry; OutOfRange if it does not fit the
        entry's type and bits."""
        if self._float is not None:
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                try:
                    packed = self._float.pack(value)
                except (OverflowError, struct.error):
                    raise OutOfRange("%r does not fit %s" % (value, self.type)) from None
                return int.from_bytes(packed, "little")
            raise OutOfRange("%r is not a number (%s)" % (value, self.type))
        if not isinstance(value, int):  # bool is an int: True/False write 1/0
            raise OutOfRange("%r is not an integer (entry 0x%04X:%02X is %s)"
                             % (value, self.index, self.subindex, self.type or "untyped"))
        bits = self.bit_length
        if self.signed and bits:
            low, high = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        else:
            low, high = 0, (1 << bits) - 1
        if not low <= value <= high:
            raise OutOfRange("%d does not fit the entry 0x%04X:%02X (%s, %d bits: %d..%d)"
                             % (value, self.index, self.subindex, self.type or "untyped",
                                bits, low, high))
        return value & ((1 << bits) - 1)

    def __repr__(self):
        return ("Entry(slave=%d, 0x%04X:%02X %s %s, bit %d+%d, %r)"
                % (self.slave, self.index, self.subindex, self.direction,
                   self.type or "type 0x%04X" % self.type_code, self.bit_offset,
                   self.bit_length, self.name))


# --- lines (the Rust client's protocol.rs) -------------------------------------------------

_EVENTS = ("layout_changed", "watchdog", "shutdown")


def _number(word, line):
    if not word or not all("0" <= c <= "9" for c in word):
        raise ProtocolError("%r: %r is not a number" % (line[:MAX_LINE // 2], word))
    return int(word)


def _generation(word, line):
    generation = _number(word, line)
    if generation > 0xFFFFFFFF:
        raise ProtocolError("%s: generation too large" % word)
    return generation


def parse_line(line):
    """One line from ecatd (without its newline) as a tuple: ``("hello", generation,
    region bytes)``, ``("claimed", region bytes)``, ``("released",)``, ``("pong",)``,
    ``("refused", reason)``, ``("layout_changed", generation)``, ``("watchdog",)`` or
    ``("shutdown",)``."""
    words = line.split(" ", 2)
    if words[0] == "OK" and len(words) == 3 and words[1] == "HELLO":
        numbers = words[2].split(" ", 1)
        if len(numbers) != 2:
            raise ProtocolError("%r: two numbers expected" % line[:MAX_LINE // 2])
        return ("hello", _generation(numbers[0], line), _number(numbers[1], line))
    if words[0] == "OK" and len(words) == 3 and words[1] == "CLAIM":
        return ("claimed", _number(words[2], line))
    if words == ["OK", "RELEASE"]:
        return ("released",)
    if words == ["OK", "PING"]:
        return ("pong",)
    if words[0] == "ERR":
        return ("refused", " ".join(words[1:]))
    if words[0] == "EVENT" and len(words) == 3 and words[1] == "layout_changed":
        return ("layout_changed", _generation(words[2], line))
    if words == ["EVENT", "watchdog"]:
        return ("watchdog",)
    if words == ["EVENT", "shutdown"]:
        return ("shutdown",)
    raise ProtocolError("unknown line %r" % line[:MAX_LINE // 2])


def _refusal(line):
    if line[0] == "refused":
        return Refused(line[1])
    return ProtocolError("unexpected answer %r" % (line,))


# --- shared memory helpers ---------------------------------------------------------------

def _load_u32(region, offset):
    """The u32 at ``offset``; 0 outside the region (as the Rust Mapping)."""
    if offset + 4 > len(region):
        return 0
    return _U32.unpack_from(region, offset)[0]


def _load_u64(region, offset):
    """The u64 at ``offset`` (one 8-byte load); 0 outside the region."""
    if offset + 8 > len(region):
        return 0
    return _U64.unpack_from(region, offset)[0]


def _map(fd, length, writable):
    if length == 0 or length % PAGE:
        raise ProtocolError("region of %d bytes: not a whole number of pages" % length)
    try:
        if writable:
            return mmap.mmap(fd, length, flags=mmap.MAP_SHARED,
                             prot=mmap.PROT_READ | mmap.PROT_WRITE)
        return mmap.mmap(fd, length, access=mmap.ACCESS_READ)  # MAP_SHARED, PROT_READ
    except (OSError, ValueError) as err:  # ValueError: the file is shorter than `length`
        raise Error("cannot map the region of %d bytes: %s" % (length, err)) from err


def _close_fds(fds):
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass
    del fds[:]


# --- the attachment (the Rust client's client.rs) ----------------------------------------

def connect(path=None, read_only=False):
    """Attaches to ecatd's socket at ``path`` (None: ``$ECAT_APP_SOCKET``, else
    ``/run/ecatd/app.sock``); ``read_only`` attaches a monitor that can never claim.
    Returns an :class:`App`."""
    return App(path, read_only)


class App:
    """A control program attached to ecatd: the layout, the last cycle's image and (once
    claimed) the outputs. :meth:`wait` copies a whole cycle, so every :meth:`read` until the
    next wait sees that one cycle."""

    def __init__(self, path=None, read_only=False):
        self._sock = None
        self._events = -1
        self._image = None
        self._commit = None       # the commit region's mapping while this program owns
        self._pending = bytearray()  # bytes read that are not a whole line yet
        self._ended = None        # once set, (class, args) every wait raises again
        path = os.fspath(path) if path is not None else default_socket()
        try:
            self._attach(path, read_only)
        except BaseException:
            self.close()
            raise

    def _attach(self, path, read_only):
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock = sock
        try:
            sock.connect(path)
        except OSError as err:
            raise Error("cannot attach to %s: %s" % (path, err)) from err
        # An answer not back in this long means ecatd is stuck; wait polls on its own.
        sock.settimeout(ANSWER_TIMEOUT)
        self._send("HELLO %d %s" % (PROTOCOL_VERSION, "ro" if read_only else "rw"))
        fds = []
        try:
            line = self._answer(fds)
            if line[0] != "hello":
                raise _refusal(line)
            if len(fds) != 2:
                raise ProtocolError("HELLO without its two descriptors")
            self.generation = line[1]
            image = _map(fds[0], line[2], writable=False)
            self._image = image
            self._events = fds.pop()
        finally:
            _close_fds(fds)
        # Reading the eventfd must never block (another thread may drain it first). The
        # flag is the open file's, shared with ecatd, whose writes it does not change.
        os.set_blocking(self._events, False)
        self._poll = select.poll()
        self._poll.register(self._events, select.POLLIN)
        self._poll.register(sock.fileno(), select.POLLIN)

        if image[_I_MAGIC:_I_MAGIC + 8] != IMAGE_MAGIC or \
                _load_u32(image, _I_VERSION) != LAYOUT_VERSION:
            raise ProtocolError("not an image region of layout version 1")
        image_len = _load_u32(image, _I_IMAGE_LEN)
        count = _load_u32(image, _I_ENTRY_COUNT)
        table = _load_u32(image, _I_ENTRIES)
        if _load_u32(image, _I_ENTRY_SIZE) != ENTRY_SIZE:
            raise ProtocolError("entry size is not 64")
        entries = []
        for i in range(count):
            at = table + i * ENTRY_SIZE
            if at + ENTRY_SIZE > len(image):
                raise ProtocolError("entry table beyond the region")
            entry = Entry.decode(image[at:at + ENTRY_SIZE])
            if entry is None or not entry.fits(image_len):
                raise ProtocolError("entry %d is malformed" % i)
            entries.append(entry)
        slots, stride, inputs_at, outputs_at, length = image_shape(image_len, count)
        if _load_u32(image, _I_SLOTS) != slots or \
                _load_u32(image, _I_SLOT_STRIDE) != stride or \
                _load_u32(image, _I_SLOT_COUNT) != SLOTS or length > len(image):
            raise ProtocolError("slots do not match the image size")

        self.entries = entries
        self._by_key = {}
        for entry in entries:  # the first of duplicates wins, as App::entry finds it
            self._by_key.setdefault((entry.slave, entry.index, entry.subindex), entry)
        self._image_len = image_len
        self._slots = slots
        self._stride = stride
        self._inputs_at = inputs_at
        self._outputs_at = outputs_at
        self._cycle = 0
        self._published_ns = 0
        self._inputs = bytes(image_len)
        self._sent = bytes(image_len)
        self._outputs = bytearray(image_len)  # what this program will commit
        self._last_commit = 0
        # Start from the newest cycle, so the first read sees real values.
        self._copy_newest()

    # -- the layout and the cycle --

    @property
    def cycle(self):
        """The last cycle :meth:`wait` returned (or connect copied; 0: none yet)."""
        return self._cycle

    @property
    def published_ns(self):
        """When ecatd published the last cycle :meth:`wait` returned: CLOCK_MONOTONIC in
        nanoseconds, the clock every process on this machine shares, so
        ``time.clock_gettime_ns(time.CLOCK_MONOTONIC)`` right after the wait minus this is
        the wake-up latency. Copied with the cycle (one consistent slot). 0 before the
        first cycle, or from an ecatd that does not write it."""
        return self._published_ns

    @property
    def period(self):
        """The cycle period ecatd runs, in seconds."""
        return _load_u64(self._image, _I_PERIOD_NS) / 1e9

    @property
    def applied(self):
        """The commit number the last frame carried (0: none of this layout yet)."""
        return _load_u64(self._image, _I_APPLIED)

    @property
    def owns(self):
        """Whether this program owns the outputs."""
        return self._commit is not None

    def entry(self, slave, index, subindex):
        """The :class:`Entry` ``index:subindex`` of the slave at ring position ``slave``;
        NoSuchEntry if the layout maps none."""
        entry = self._by_key.get((slave, index, subindex))
        if entry is None:
            raise NoSuchEntry(slave, index, subindex)
        return entry

    # -- ownership --

    def claim(self):
        """Takes the outputs. Refused (:class:`Refused`, with the owner's pid and uid) while
        another program owns them; from now on this program's commits are what the cycle
        sends."""
        self._check_ended()
        self._send("CLAIM")
        fds = []
        try:
            line = self._answer(fds)
            if line[0] != "claimed":
                raise _refusal(line)
            if len(fds) != 1:
                raise ProtocolError("CLAIM without its descriptor")
            region = _map(fds[0], line[1], writable=True)
        finally:
            _close_fds(fds)
        stride, length = commit_shape(self._image_len)
        if region[_C_MAGIC:_C_MAGIC + 8] != COMMIT_MAGIC or \
                _load_u32(region, _C_GENERATION) != self.generation or \
                _load_u32(region, _C_IMAGE_LEN) != self._image_len or \
                _load_u32(region, _C_SLOTS) != _C_FIRST_SLOT or \
                _load_u32(region, _C_SLOT_STRIDE) != stride or \
                _load_u32(region, _C_SLOT_COUNT) != SLOTS or length > len(region):
            region.close()
            raise ProtocolError("the commit region does not match the layout")
        self._drop_commit()
        # Outputs this program does not write keep what the cycle sends now.
        self._outputs[:] = self._sent
        self._commit_stride = stride
        # Continue the numbering: ecatd takes only a commit newer than the last it saw.
        self._last_commit = _load_u64(region, _C_COMMIT)
        self._commit = region

    def release(self):
        """Gives the outputs back (the safe outputs go out from the next cycle)."""
        if self._commit is None:
            return
        self._drop_commit()
        self._send("RELEASE")
        fds = []
        try:
            line = self._answer(fds)
        finally:
            _close_fds(fds)
        if line[0] != "released":
            raise _refusal(line)

    # -- the cycle --

    def wait(self, timeout=1.0):
        """Blocks until a cycle newer than the last one returned has completed (returns at
        once if one already has), copies its image and returns its number. ``timeout`` in
        seconds (None: no limit). Raises Timeout, LayoutChanged, Watchdog or Closed."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            self._check_ended()
            if _load_u32(self._image, _I_FLAGS) & FLAG_STALE:
                # The region does not say which generation replaced it: the next one.
                generation = self.generation + 1
                self._end(LayoutChanged, generation)
                raise LayoutChanged(generation)
            if _load_u64(self._image, _I_CYCLE) > self._cycle and self._copy_newest():
                return self._cycle
            if b"\n" in self._pending:
                # Event lines that came in with an earlier answer: the socket will not
                # become readable for them again.
                self._take_events(more=None)
                continue
            if deadline is None:
                left = None
            else:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise Timeout()
                left = max(1, math.ceil(left * 1000))  # ms; never a busy 0
            ready = dict(self._poll.poll(left))
            if ready.get(self._events):
                try:
                    os.read(self._events, 8)
                except BlockingIOError:
                    pass  # drained by another thread
            if ready.get(self._sock.fileno()):
                self._read_events()

    def read(self, slave, index, subindex):
        """The value of the entry in the last cycle: an int (sign-extended for the signed
        types; 0/1 for BOOLEAN) or a float for REAL32/REAL64. An input as received; an
        output as this program will commit it when it owns the outputs, else as the cycle
        sent it."""
        entry = self.entry(slave, index, subindex)
        if entry.direction == "in":
            return entry.value(self._inputs)
        return entry.value(self._outputs if self._commit is not None else self._sent)

    def read_raw(self, slave, index, subindex):
        """The entry's raw bits in the last cycle as received (inputs) or sent (outputs)."""
        entry = self.entry(slave, index, subindex)
        return entry.get(self._inputs if entry.direction == "in" else self._sent)

    def write(self, slave, index, subindex, value):
        """Sets the output entry to ``value`` for the next :meth:`commit`. NotOutput for an
        input, OutOfRange for a value its type and bits cannot hold."""
        entry = self.entry(slave, index, subindex)
        if entry.direction != "out":
            raise NotOutput("entry 0x%04X:%02X of slave %d is an input"
                            % (index, subindex, slave))
        raw = entry.encode(value)
        if not entry.set(self._outputs, raw):
            raise OutOfRange("entry 0x%04X:%02X lies outside the image" % (index, subindex))

    def commit(self):
        """Hands ecatd every output written so far as one whole (docs/application.md,
        "Committing"): the next cycle's frame carries all of them. Returns the commit
        number."""
        self._check_ended()
        region = self._commit
        if region is None:
            raise NotOwner()
        number = self._last_commit + 1
        slot = _C_FIRST_SLOT + (number % SLOTS) * self._commit_stride
        data = slot + SLOT_HEADER
        _U64.pack_into(region, slot, 0)          # the slot is being written
        region[data:data + self._image_len] = self._outputs
        _U64.pack_into(region, slot, number)     # whole
        _U64.pack_into(region, _C_COMMIT, number)
        self._last_commit = number
        return number

    # -- the end --

    def close(self):
        """Detaches (an owner's outputs go to their safe values from the next cycle)."""
        self._drop_commit()
        if self._image is not None:
            self._image.close()
            self._image = None
        if self._events >= 0:
            os.close(self._events)
            self._events = -1
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    # -- internals --

    def _copy_newest(self):
        """Copies the newest published cycle (the seqlock reader of docs/application.md,
        "Reading a cycle"); False if there is none or it was overwritten while copying."""
        image = self._image
        cycle = _load_u64(image, _I_CYCLE)
        if cycle == 0:
            return False
        slot = self._slots + (cycle % SLOTS) * self._stride
        if _load_u64(image, slot) != cycle:
            return False
        published = _load_u64(image, slot + SLOT_PUBLISHED_NS)
        at = slot + self._inputs_at
        inputs = image[at:at + self._image_len]
        at = slot + self._outputs_at
        sent = image[at:at + self._image_len]
        if _load_u64(image, slot) != cycle:
            return False  # ecatd reused the slot while we copied: more than two cycles slow
        self._inputs, self._sent, self._cycle = inputs, sent, cycle
        self._published_ns = published
        return True

    def _drop_commit(self):
        if self._commit is not None:
            self._commit.close()
            self._commit = None

    def _end(self, cls, *args):
        """Makes every further wait (and claim, commit) raise ``cls(*args)``."""
        self._ended = (cls, args)
        self._drop_commit()

    def _check_ended(self):
        if self._ended is not None:
            cls, args = self._ended
            raise cls(*args)
        if self._sock is None:
            raise Closed("the attachment is closed")

    def _send(self, text):
        line = (text + "\n").encode("ascii")
        assert len(line) <= MAX_LINE
        try:
            self._sock.sendall(line, socket.MSG_NOSIGNAL)
        except (BrokenPipeError, ConnectionResetError):
            self._end(Closed)
            raise Closed() from None
        except OSError as err:
            raise Error("cannot send to ecatd: %s" % err) from err

    def _fill(self, fds):
        """Reads more bytes into the line buffer, taking the descriptors that come with
        them (closed on exec); returns the bytes read (0: ecatd closed the connection)."""
        try:
            data, ancillary, flags, _ = self._sock.recvmsg(
                MAX_LINE, socket.CMSG_SPACE(MAX_FDS * 4), socket.MSG_CMSG_CLOEXEC)
        except socket.timeout:
            raise Error("no answer from ecatd within %g s" % ANSWER_TIMEOUT) from None
        except ConnectionResetError:
            data, ancillary, flags = b"", [], 0
        except OSError as err:
            raise Error("cannot read from ecatd: %s" % err) from err
        for level, kind, payload in ancillary:
            if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
                received = array.array("i")
                received.frombytes(payload[:len(payload) - len(payload) % received.itemsize])
                fds.extend(received)
        if flags & socket.MSG_CTRUNC:
            _close_fds(fds)
            raise ProtocolError("more descriptors than expected")
        self._pending += data
        return len(data)

    def _take_line(self):
        """The first whole line in the buffer, parsed and taken out of it; None if there is
        none yet. A line over MAX_LINE bytes ends the attachment."""
        end = self._pending.find(b"\n")
        if (end < 0 and len(self._pending) >= MAX_LINE) or end + 1 > MAX_LINE:
            message = "a line from ecatd is longer than %d bytes" % MAX_LINE
            self._end(ProtocolError, message)
            raise ProtocolError(message)
        if end < 0:
            return None
        text = self._pending[:end].decode("utf-8", "replace")
        del self._pending[:end + 1]
        return parse_line(text)

    def _answer(self, fds):
        """The answer to the request just sent; events before it are taken as they come."""
        while True:
            line = self._take_line()
            if line is None:
                if self._fill(fds) == 0:
                    self._end(Closed)
                    raise Closed()
                continue
            if line[0] not in _EVENTS:
                return line
            try:
                self._event(line)  # a watchdog before the answer still ends the ownership
            except Error:
                pass
            self._check_ended()

    def _read_events(self):
        """Reads the event lines waiting on the socket; the first that ends something is
        raised."""
        fds = []
        try:
            more = self._fill(fds)
        finally:
            _close_fds(fds)  # descriptors only come with answers
        self._take_events(more)

    def _take_events(self, more):
        first = None
        while True:
            line = self._take_line()
            if line is None:
                break
            try:
                self._event(line)
            except Error as err:
                first = first or err
        if more == 0:
            self._end(Closed)
            raise first or Closed()
        if first is not None:
            raise first

    def _event(self, line):
        kind = line[0]
        if kind == "layout_changed":
            self._end(LayoutChanged, line[1])
            raise LayoutChanged(line[1])
        if kind == "watchdog":
            self._drop_commit()
            raise Watchdog()
        if kind == "shutdown":
            self._end(Closed)
            raise Closed()
        raise ProtocolError("unexpected line %r" % (line,))
