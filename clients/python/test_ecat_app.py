"""Self-tests of the application clients (docs/application.md) without ecatd.

    python3 -m unittest discover -s clients/python -v

The Python client runs in process against fake_ecatd.FakeEcatd. The C client's test
program (clients/c/test_client.c) and both examples are compiled with ``cc`` into a
temporary directory and run against the same fake; those tests are skipped when ``cc`` is
missing.
"""

import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import unittest
from unittest import mock

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import ecat_app  # noqa: E402
import fake_ecatd  # noqa: E402

C_DIR = os.path.join(os.path.dirname(HERE), "c")
CFLAGS = ["-O2", "-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic"]


class Attached(unittest.TestCase):
    """A fresh fake ecatd with the test layout for every test."""

    fake_options = {"initial_commit": 4}

    def setUp(self):
        self.fake = fake_ecatd.FakeEcatd(**self.fake_options)
        self.addCleanup(self.fake.close)

    def attach(self, **options):
        app = ecat_app.connect(self.fake.path, **options)
        self.addCleanup(app.close)
        return app

    def publish(self):
        inputs, sent = self.fake.test_images()
        return self.fake.publish(inputs, sent if self.fake.cycle == 0 else None)


class ConnectTest(Attached):
    def test_connect_reads_the_entry_table(self):
        app = self.attach()
        self.assertEqual(app.generation, 1)
        self.assertEqual(app.period, 0.001)
        self.assertEqual(app.cycle, 0)
        self.assertFalse(app.owns)
        self.assertEqual(len(app.entries), 5)
        analog = app.entries[0]
        self.assertEqual((analog.slave, analog.station, analog.pdo, analog.index,
                          analog.subindex), (2, 0x1002, 0x1A00, 0x6000, 1))
        self.assertEqual((analog.type, analog.type_code, analog.direction),
                         ("INTEGER16", 3, "in"))
        self.assertEqual((analog.bit_offset, analog.bit_length), (3, 16))
        self.assertEqual(analog.name, "Analog input")
        out = app.entry(1, 0x7000, 1)
        self.assertEqual((out.type, out.direction, out.bit_offset, out.bit_length),
                         ("BOOLEAN", "out", 69, 1))
        self.assertEqual([e.type for e in app.entries],
                         ["INTEGER16", "UNSIGNED32", "BOOLEAN", "INTEGER8", "REAL32"])

    def test_connect_copies_the_newest_cycle(self):
        self.publish()
        self.publish()
        app = self.attach()
        self.assertEqual(app.cycle, 2)
        self.assertEqual(app.read(2, 0x6000, 1), -2)

    def test_the_socket_comes_from_the_environment(self):
        with mock.patch.dict(os.environ, {"ECAT_APP_SOCKET": self.fake.path}):
            self.assertEqual(ecat_app.default_socket(), self.fake.path)
            with ecat_app.connect() as app:
                self.assertEqual(len(app.entries), 5)
        with mock.patch.dict(os.environ, clear=True):
            self.assertEqual(ecat_app.default_socket(), "/run/ecatd/app.sock")

    def test_no_socket_is_an_error(self):
        with self.assertRaisesRegex(ecat_app.Error, "cannot attach to /nonexistent"):
            ecat_app.connect("/nonexistent/app.sock")

    def test_close_and_context_manager(self):
        with ecat_app.connect(self.fake.path) as app:
            pass
        with self.assertRaises(ecat_app.Closed):
            app.wait(0)
        app.close()  # twice is fine


class SplitAnswersTest(Attached):
    """The descriptors come with the first bytes of an answer, the rest later."""

    fake_options = {"initial_commit": 4, "split_answers": True}

    def test_answers_in_pieces(self):
        app = self.attach()
        self.assertEqual(len(app.entries), 5)
        app.claim()
        self.assertTrue(app.owns)
        self.assertEqual(app.commit(), 5)


class CycleTest(Attached):
    def test_wait_returns_the_new_cycle_and_read_decodes(self):
        app = self.attach()
        self.publish()
        self.assertEqual(app.wait(timeout=2.0), 1)
        self.assertEqual(app.cycle, 1)
        self.assertEqual(app.read(2, 0x6000, 1), -2)            # INTEGER16 at bit 3
        self.assertEqual(app.read_raw(2, 0x6000, 1), 0xFFFE)
        self.assertEqual(app.read(2, 0x6010, 1), 0xDEADBEEF)    # UNSIGNED32, not negative
        value = app.read(2, 0x6020, 0x11)                        # REAL32
        self.assertIsInstance(value, float)
        self.assertEqual(value, 21.5)
        self.assertEqual(app.read(1, 0x7000, 1), 1)              # outputs as sent
        self.assertEqual(app.read(1, 0x7010, 2), -5)

    def test_wait_gives_the_time_the_cycle_was_published(self):
        app = self.attach()
        self.assertEqual(app.published_ns, 0)
        before = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        self.publish()
        self.assertEqual(app.wait(timeout=2.0), 1)
        published = app.published_ns
        self.assertGreaterEqual(published, before)
        self.assertLessEqual(published, time.clock_gettime_ns(time.CLOCK_MONOTONIC))
        self.publish()
        self.assertEqual(app.wait(timeout=2.0), 2)
        self.assertGreaterEqual(app.published_ns, published)

    def test_wait_returns_at_once_when_a_cycle_is_already_there(self):
        app = self.attach()
        self.publish()
        self.publish()
        start = time.monotonic()
        self.assertEqual(app.wait(timeout=5.0), 2)  # the newest, skipping 1
        self.assertLess(time.monotonic() - start, 1.0)
        with self.assertRaises(ecat_app.Timeout):
            app.wait(timeout=0.05)

    def test_wait_wakes_on_a_cycle_published_while_waiting(self):
        app = self.attach()
        timer = threading.Timer(0.1, self.publish)
        timer.start()
        self.addCleanup(timer.cancel)
        start = time.monotonic()
        self.assertEqual(app.wait(timeout=5.0), 1)
        self.assertLess(time.monotonic() - start, 2.0)

    def test_timeout(self):
        app = self.attach()
        start = time.monotonic()
        with self.assertRaises(ecat_app.Timeout) as caught:
            app.wait(timeout=0.1)
        self.assertGreaterEqual(time.monotonic() - start, 0.1)
        self.assertIsInstance(caught.exception, ecat_app.Error)
        self.publish()
        self.assertEqual(app.wait(timeout=2.0), 1)  # a timeout is not sticky

    def test_a_torn_slot_is_not_returned(self):
        app = self.attach()
        self.publish()
        # ecatd in the middle of rewriting the slot: stamp 0.
        slot = self.fake.slots + (1 % 3) * self.fake.stride
        struct.pack_into("<Q", self.fake.image, slot, 0)
        with self.assertRaises(ecat_app.Timeout):
            app.wait(timeout=0.05)
        self.assertEqual(app.cycle, 0)
        struct.pack_into("<Q", self.fake.image, slot, 1)
        self.assertEqual(app.wait(timeout=0.05), 1)

    def test_unknown_entry(self):
        app = self.attach()
        with self.assertRaisesRegex(ecat_app.NoSuchEntry, "slave 3 maps no entry 0x6000:01"):
            app.read(3, 0x6000, 1)
        with self.assertRaisesRegex(ecat_app.Error, "0x7000:09"):
            app.write(1, 0x7000, 9, 1)


class OwnershipTest(Attached):
    def test_write_and_commit_put_the_bits_in_slot_n_mod_3(self):
        app = self.attach()
        self.publish()
        app.wait(2.0)
        app.claim()
        self.assertTrue(app.owns)
        # The pending outputs start as the last cycle sent them.
        self.assertEqual(app.read(1, 0x7000, 1), 1)
        self.assertEqual(app.read(1, 0x7010, 2), -5)
        app.write(1, 0x7000, 1, 0)
        app.write(1, 0x7010, 2, -128)
        self.assertEqual(app.read(1, 0x7010, 2), -128)  # the pending value
        self.assertEqual(app.commit(), 5)                # the region said 4
        self.assertEqual(self.fake.commit_number(), 5)
        stamp, data = self.fake.commit_slot(5)           # slot 5 % 3 = 2
        self.assertEqual(stamp, 5)
        out, setpoint = self.fake.entries[2], self.fake.entries[3]
        self.assertEqual(fake_ecatd.get_bits(data, out), 0)
        self.assertEqual(fake_ecatd.signed_bits(data, setpoint), -128)
        self.assertEqual(data[9], 0x80)
        app.write(1, 0x7000, 1, True)
        self.assertEqual(app.commit(), 6)                # slot 0
        stamp, data = self.fake.commit_slot(6)
        self.assertEqual(stamp, 6)
        self.assertEqual(fake_ecatd.get_bits(data, out), 1)
        self.assertEqual(data[8], 1 << 5)                # bit 69 alone in byte 8
        # The next frame carries commit 6.
        self.publish()
        self.assertEqual(app.wait(2.0), 2)
        self.assertEqual(app.applied, 6)

    def test_write_checks_the_entry_and_the_range(self):
        app = self.attach()
        with self.assertRaises(ecat_app.NotOutput):
            app.write(2, 0x6000, 1, 1)
        for bad in (2, -1):
            with self.assertRaisesRegex(ecat_app.OutOfRange, "does not fit"):
                app.write(1, 0x7000, 1, bad)
        for bad in (128, -129):
            with self.assertRaisesRegex(ecat_app.OutOfRange, "-128..127"):
                app.write(1, 0x7010, 2, bad)
        with self.assertRaisesRegex(ecat_app.OutOfRange, "not an integer"):
            app.write(1, 0x7010, 2, 1.5)
        app.write(1, 0x7010, 2, 127)
        app.write(1, 0x7010, 2, -128)

    def test_commit_needs_ownership(self):
        app = self.attach()
        with self.assertRaises(ecat_app.NotOwner):
            app.commit()

    def test_a_refused_claim_says_why(self):
        self.fake.claim_refusal = "owned pid=123 uid=0"
        app = self.attach()
        with self.assertRaises(ecat_app.Error) as caught:
            app.claim()
        self.assertIsInstance(caught.exception, ecat_app.Refused)
        self.assertEqual(caught.exception.reason, "owned pid=123 uid=0")
        self.assertIn("owned pid=123 uid=0", str(caught.exception))
        self.assertFalse(app.owns)

    def test_a_second_claimer_learns_the_owner(self):
        owner = self.attach()
        owner.claim()
        other = self.attach()
        with self.assertRaisesRegex(ecat_app.Refused,
                                    "owned pid=%d uid=%d" % (os.getpid(), os.getuid())):
            other.claim()
        owner.release()
        self.assertFalse(owner.owns)
        other.claim()
        self.assertTrue(other.owns)

    def test_a_monitor_cannot_claim(self):
        app = self.attach(read_only=True)
        with self.assertRaisesRegex(ecat_app.Refused, "read-only attachment"):
            app.claim()

    def test_the_watchdog_takes_the_outputs_once(self):
        app = self.attach()
        app.claim()
        self.fake.watchdog()
        with self.assertRaises(ecat_app.Watchdog):
            app.wait(2.0)
        self.assertFalse(app.owns)
        with self.assertRaises(ecat_app.NotOwner):
            app.commit()
        with self.assertRaises(ecat_app.Timeout):  # not sticky
            app.wait(0.05)
        app.claim()
        self.assertEqual(app.commit(), 5)


class EventTest(Attached):
    def test_layout_changed_is_sticky(self):
        app = self.attach()
        app.claim()
        self.fake.send_all(b"EVENT layout_changed 2\n")
        with self.assertRaises(ecat_app.LayoutChanged) as caught:
            app.wait(2.0)
        self.assertEqual(caught.exception.generation, 2)
        self.assertIn("generation 2", str(caught.exception))
        self.assertFalse(app.owns)
        self.publish()
        with self.assertRaises(ecat_app.LayoutChanged):
            app.wait(0)
        with self.assertRaises(ecat_app.LayoutChanged):
            app.claim()
        with self.assertRaises(ecat_app.LayoutChanged):
            app.commit()

    def test_a_stale_region_is_a_layout_change(self):
        app = self.attach()
        self.fake.mark_stale()
        with self.assertRaises(ecat_app.LayoutChanged) as caught:
            app.wait(2.0)
        self.assertEqual(caught.exception.generation, 2)

    def test_eof_is_closed_for_good(self):
        app = self.attach()
        self.fake.disconnect_all()
        with self.assertRaises(ecat_app.Closed):
            app.wait(2.0)
        with self.assertRaises(ecat_app.Closed):
            app.wait(0)
        with self.assertRaises(ecat_app.Closed):
            app.claim()

    def test_shutdown_is_closed(self):
        app = self.attach()
        self.fake.send_all(b"EVENT shutdown\n")
        with self.assertRaises(ecat_app.Closed):
            app.wait(2.0)
        with self.assertRaises(ecat_app.Closed):
            app.wait(0)

    def test_an_event_line_in_pieces(self):
        app = self.attach()
        self.fake.send_all(b"EVENT watch")
        with self.assertRaises(ecat_app.Timeout):
            app.wait(0.05)
        self.fake.send_all(b"dog\n")
        with self.assertRaises(ecat_app.Watchdog):
            app.wait(2.0)

    def test_a_line_over_256_bytes_is_an_error(self):
        app = self.attach()
        self.fake.send_all(b"EVENT " + b"x" * 300 + b"\n")
        with self.assertRaisesRegex(ecat_app.ProtocolError, "longer than 256 bytes"):
            app.wait(2.0)
        with self.assertRaises(ecat_app.ProtocolError):
            app.wait(0)

    def test_a_line_of_256_bytes_is_fine(self):
        app = self.attach()
        line = b"EVENT layout_changed " + b"0" * (255 - 22) + b"7\n"
        self.assertEqual(len(line), 256)
        self.fake.send_all(line)
        with self.assertRaises(ecat_app.LayoutChanged) as caught:
            app.wait(2.0)
        self.assertEqual(caught.exception.generation, 7)

    def test_an_unknown_line_is_a_protocol_error(self):
        app = self.attach()
        self.fake.send_all(b"EVENT unheard_of\n")
        with self.assertRaisesRegex(ecat_app.ProtocolError, "unknown line"):
            app.wait(2.0)


class RawServer:
    """A server that answers HELLO with whatever a test wants (no fake needed)."""

    def __init__(self, reply, fds=()):
        self.dir = tempfile.mkdtemp(prefix="ecat-app-raw-")
        self.path = os.path.join(self.dir, "app.sock")
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.listener.bind(self.path)
        self.listener.listen(1)
        self.thread = threading.Thread(target=self.serve, args=(reply, fds), daemon=True)
        self.thread.start()

    def serve(self, reply, fds):
        conn, _ = self.listener.accept()
        with conn:
            conn.recv(256)
            if fds:
                socket.send_fds(conn, [reply], list(fds))
            else:
                conn.sendall(reply)
            try:
                conn.recv(256)  # until the client hangs up
            except ConnectionResetError:
                pass

    def close(self):
        self.listener.close()
        shutil.rmtree(self.dir, ignore_errors=True)


class HandshakeTest(unittest.TestCase):
    def connect_to(self, reply, fds=()):
        server = RawServer(reply, fds)
        self.addCleanup(server.close)
        return ecat_app.connect(server.path)

    def test_a_refused_hello(self):
        with self.assertRaisesRegex(ecat_app.Refused, "unsupported protocol version"):
            self.connect_to(b"ERR unsupported protocol version\n")

    def test_a_hello_without_descriptors(self):
        with self.assertRaisesRegex(ecat_app.ProtocolError, "two descriptors"):
            self.connect_to(b"OK HELLO 1 4096\n")

    def test_a_long_answer(self):
        with self.assertRaisesRegex(ecat_app.ProtocolError, "longer than 256 bytes"):
            self.connect_to(b"OK HELLO " + b"1" * 300 + b"\n")

    def test_a_region_that_is_not_one(self):
        fd = os.memfd_create("not-an-image")
        self.addCleanup(os.close, fd)
        os.ftruncate(fd, 4096)
        with self.assertRaisesRegex(ecat_app.ProtocolError, "not an image region"):
            self.connect_to(b"OK HELLO 1 4096\n", [fd, fd])

    def test_a_region_larger_than_its_file(self):
        fd = os.memfd_create("short")
        self.addCleanup(os.close, fd)
        os.ftruncate(fd, 4096)
        with self.assertRaisesRegex(ecat_app.Error, "cannot map"):
            self.connect_to(b"OK HELLO 1 8192\n", [fd, fd])


class EntryTest(unittest.TestCase):
    """Bits at any offset, as the Rust client's entry.rs tests them."""

    def entry(self, bit_offset, bit_length, type_code, direction="in"):
        return ecat_app.Entry(3, 1004, 0x1A00, 0x6064, 0, direction, type_code,
                              bit_offset, bit_length, "Position actual value")

    def test_bits_at_any_offset_read_back_signed_and_unsigned(self):
        image = bytearray(8)
        e = self.entry(3, 16, 0x0003)
        self.assertTrue(e.set(image, e.encode(-2)))
        self.assertEqual(e.get(image), 0xFFFE)
        self.assertEqual(e.value(image), -2)
        self.assertEqual(image[0] & 0b111, 0)
        self.assertEqual(self.entry(3, 16, 0x0006).value(image), 0xFFFE)
        bit = self.entry(63, 1, 0x0001)
        self.assertTrue(bit.set(image, 1))
        self.assertEqual(image[7], 0x80)
        self.assertFalse(self.entry(60, 8, 0x0005).set(image, 1))
        self.assertEqual(self.entry(60, 8, 0x0005).get(image), 0)

    def test_64_bit_and_float_entries(self):
        image = bytearray(16)
        i64 = self.entry(5, 64, 0x0015)
        i64.set(image, i64.encode(-(1 << 63)))
        self.assertEqual(i64.value(image), -(1 << 63))
        u64 = self.entry(5, 64, 0x001B)
        u64.set(image, u64.encode((1 << 64) - 1))
        self.assertEqual(u64.value(image), (1 << 64) - 1)
        with self.assertRaises(ecat_app.OutOfRange):
            u64.encode(-1)
        real = self.entry(7, 32, 0x0008)
        real.set(image, real.encode(-0.25))
        self.assertEqual(real.value(image), -0.25)
        with self.assertRaises(ecat_app.OutOfRange):
            real.encode(1e300)
        self.assertEqual(self.entry(0, 16, 0x0008).value(bytes(8)), 0)  # REAL32 of 16 bits

    def test_values_outside_the_type_are_not_accepted(self):
        self.assertEqual(self.entry(0, 16, 0x0003).encode(-32768), 0x8000)
        with self.assertRaises(ecat_app.OutOfRange):
            self.entry(0, 16, 0x0003).encode(32768)
        self.assertEqual(self.entry(0, 8, 0x0005).encode(255), 255)
        with self.assertRaises(ecat_app.OutOfRange):
            self.entry(0, 8, 0x0005).encode(-1)
        self.assertEqual(self.entry(0, 1, 0x0001).encode(True), 1)
        with self.assertRaises(ecat_app.OutOfRange):
            self.entry(0, 1, 0x0001).encode(2)

    def test_a_record_decodes(self):
        record = struct.pack("<HHHHBBHIH46s", 3, 1004, 0x1A00, 0x6064, 0, 1, 0x0004, 37, 32,
                             "é".encode() * 23)
        e = ecat_app.Entry.decode(record)
        self.assertEqual((e.slave, e.direction, e.type, e.bit_offset), (3, "out", "INTEGER32", 37))
        self.assertEqual(e.name, "é" * 23)
        self.assertIsNone(ecat_app.Entry.decode(record[:9] + b"\x02" + record[10:]))
        unknown = ecat_app.Entry.decode(record[:10] + b"\x00\x00" + record[12:])
        self.assertIsNone(unknown.type)
        self.assertEqual(unknown.type_code, 0)


class LineTest(unittest.TestCase):
    def test_lines_parse(self):
        parse = ecat_app.parse_line
        self.assertEqual(parse("OK HELLO 3 8192"), ("hello", 3, 8192))
        self.assertEqual(parse("OK CLAIM 4096"), ("claimed", 4096))
        self.assertEqual(parse("OK RELEASE"), ("released",))
        self.assertEqual(parse("OK PING"), ("pong",))
        self.assertEqual(parse("ERR owned pid=12 uid=0"), ("refused", "owned pid=12 uid=0"))
        self.assertEqual(parse("EVENT layout_changed 4"), ("layout_changed", 4))
        self.assertEqual(parse("EVENT watchdog"), ("watchdog",))
        self.assertEqual(parse("EVENT shutdown"), ("shutdown",))
        for bad in ("OK HELLO 1", "OK CLAIM -1", "OK RELEASE now", "", "EVENT layout_changed x",
                    "EVENT layout_changed 4294967296"):
            with self.assertRaises(ecat_app.ProtocolError, msg=bad):
                parse(bad)


def _cc():
    return shutil.which("cc")


@unittest.skipIf(_cc() is None, "cc not found: the C client and the examples in C are not "
                 "tested (install a C compiler to run them)")
class CClientTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.build = tempfile.mkdtemp(prefix="ecat-app-c-")
        cls.test_client = cls.compile("test_client", "test_client.c")
        cls.example = cls.compile("example", "example_control_loop.c")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.build, ignore_errors=True)

    @classmethod
    def compile(cls, name, source):
        out = os.path.join(cls.build, name)
        result = subprocess.run(
            [_cc()] + CFLAGS + ["-o", out, os.path.join(C_DIR, source),
                                os.path.join(C_DIR, "ecat_app.c")],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        if result.returncode != 0:
            raise AssertionError("cc failed for %s:\n%s" % (source, result.stdout))
        return out

    def test_the_c_client_against_the_fake(self):
        with fake_ecatd.FakeEcatd(initial_commit=4, split_answers=True) as fake, \
                tempfile.TemporaryFile("w+") as stderr:
            proc = subprocess.Popen([self.test_client, fake.path], stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=stderr,
                                    universal_newlines=True)
            killer = threading.Timer(60, proc.kill)
            killer.start()
            try:
                for line in proc.stdout:  # one command per line, one reply each
                    proc.stdin.write(fake.command(line.strip()) + "\n")
                    proc.stdin.flush()
                status = proc.wait()
            finally:
                killer.cancel()
                proc.stdin.close()
                proc.stdout.close()
            stderr.seek(0)
            report = stderr.read()
        self.assertEqual(status, 0, "test_client failed:\n" + report)

    def test_the_c_example_mirrors_the_inputs(self):
        run_example(self, [self.example], [])


def run_example(test, program, socket_flag):
    """Runs an example for 30 cycles against a fake with the DI8/DO8 layout and checks that
    its last commit mirrors the inputs."""
    with fake_ecatd.FakeEcatd(fake_ecatd.IO_ENTRIES, fake_ecatd.IO_IMAGE_LEN) as fake:
        # The EL1008 reads 0x5A for ten cycles, then 0xA5.
        fake.start_publisher(0.005, inputs=lambda c: bytes([0, 0x5A if c <= 10 else 0xA5]))
        if socket_flag:
            argv = program + [socket_flag, fake.path, "--cycles", "30"]
        else:
            argv = program + [fake.path, "30"]
        result = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                universal_newlines=True, timeout=60)
        test.assertEqual(result.returncode, 0, result.stdout)
        test.assertIn("30 cycles mirrored", result.stdout)
        number = fake.commit_number()
        test.assertGreaterEqual(number, 30)
        stamp, data = fake.commit_slot(number)
        test.assertEqual(stamp, number)
        test.assertEqual(data[0], 0xA5, "the last commit mirrors the last inputs")
        test.assertGreater(fake.applied, 0, "ecatd took commits into frames")


class PythonExampleTest(Attached):
    def test_the_python_example_mirrors_the_inputs(self):
        run_example(self, [sys.executable, os.path.join(HERE, "example_control_loop.py")],
                    "--socket")

    def test_the_python_example_needs_its_entries(self):
        result = subprocess.run(
            [sys.executable, os.path.join(HERE, "example_control_loop.py"), "--socket",
             self.fake.path, "--cycles", "1"],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True,
            timeout=60)
        self.assertNotEqual(result.returncode, 0)
        self.assertIn("slave 2 maps no entry 0x6000:02", result.stdout)


if __name__ == "__main__":
    unittest.main()
