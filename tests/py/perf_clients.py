"""The Python clients of tests/benches/perf_veth.rs: each times N reads of 0x1018:01 (the
slave's vendor ID) one way and prints percentiles as JSON, as a SCADA script would do them.

Usage:
  perf_clients.py raw IFACE --count K             one APRD of AL status (AF_PACKET round trip)
  perf_clients.py gateway HOST:PORT --station S --count K   ETG.8200 over UDP
  perf_clients.py rest URL --slave P --count K    REST, HTTP/1.1 keep-alive (http.client)
  perf_clients.py grpc HOST:PORT --slave P --count K --proto DIR   gRPC (grpcio)
  perf_clients.py bringup IFACE --slaves N        pysoem config_init + config_map + OP

With `--floor` the gateway asks a station no slave has (the gateway answers it with an SDO
abort itself), REST asks `/healthz` and gRPC `GetLogFilter`: no slave behind the call, so
these time the transport and ecatd's stack alone.

Every answer is checked (the vendor ID, or the working counter). The gRPC stubs are
generated from DIR's .proto files with grpcio-tools into a temporary directory.
"""

import argparse
import http.client
import json
import os
import socket
import struct
import sys
import tempfile
import time

ETHERTYPE_ECAT = 0x88A4
PACKET_OUTGOING = 4
# ETG.1000.4 §5.4, Table 14: APRD.
APRD = 0x01
AL_STATUS = 0x0130


def timed(count, op):
    """Runs op a tenth of count times as warm-up, then count timed times."""
    for _ in range(max(count // 10, 1)):
        op()
    samples = []
    start = time.perf_counter()
    for _ in range(count):
        t = time.perf_counter()
        op()
        samples.append(time.perf_counter() - t)
    elapsed = time.perf_counter() - start
    samples.sort()
    at = lambda q: samples[int((len(samples) - 1) * q)] * 1e6
    return {"p50_us": at(0.50), "p99_us": at(0.99), "per_second": count / elapsed}


def raw(args):
    """ETG.1000.4 §5.3.2 (EtherCAT frame header) and §5.4.1.2 (datagram): one APRD of 2
    bytes to the first slave, padded to the Ethernet minimum."""
    s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETHERTYPE_ECAT))
    s.bind((args.target, ETHERTYPE_ECAT))
    s.settimeout(1.0)
    state = {"index": 0}

    def op():
        index = state["index"] = (state["index"] + 1) & 0xFF
        datagram = struct.pack("<BBhHHH", APRD, index, 0, AL_STATUS, 2, 0) + b"\0\0" + b"\0\0"
        header = struct.pack("<H", len(datagram) | (1 << 12))
        frame = b"\xff" * 6 + b"\x02\0\0\0\0\x01" + struct.pack(">H", ETHERTYPE_ECAT)
        frame += header + datagram
        frame += b"\0" * max(60 - len(frame), 0)
        s.send(frame)
        while True:
            data, addr = s.recvfrom(2048)
            if addr[2] == PACKET_OUTGOING:
                continue
            # Ethernet 14, EtherCAT header 2, datagram header 10, data 2, working counter.
            if len(data) >= 30 and data[16] == APRD and data[17] == index:
                wkc = struct.unpack_from("<H", data, 28)[0]
                if wkc != 1:
                    raise SystemExit(f"APRD working counter {wkc}")
                return

    return timed(args.count, op)


def gateway(args):
    """ETG.8200: an EtherCAT header of type 5 (mailbox; ETG.1000.4 §5.3.2, Table 11) before a
    mailbox header (ETG.1000.4 §5.6, Table 29) and a CoE SDO upload request."""
    host, port = args.target.rsplit(":", 1)
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.settimeout(5.0)
    addr = (host, int(port))
    state = {"counter": 0}
    # ETG.1000.6 §5.6.2.4: CoE header (SDO request), SDO initiate upload of 0x1018:01.
    sdo = struct.pack("<HBHB", 0x2000, 0x40, 0x1018, 1) + b"\0" * 4
    vendor = {}

    # --floor: a station no slave has, answered by the gateway itself with an SDO abort.
    station = 0x7FFE if args.floor else args.station
    want = 0x80 if args.floor else 0x40

    def op():
        state["counter"] = state["counter"] % 7 + 1
        mailbox = struct.pack("<HHBB", len(sdo), station, 0, 0x03 | (state["counter"] << 4))
        body = mailbox + sdo
        datagram = struct.pack("<H", len(body) | (5 << 12)) + body
        s.sendto(datagram, addr)
        reply, _ = s.recvfrom(2048)
        # EtherCAT header 2, mailbox header 6, CoE header 2, SDO command 1, index 2, sub 1.
        if len(reply) < 18 or reply[10] & 0xE0 != want:
            raise SystemExit(f"unexpected gateway reply {reply.hex()}")
        value = struct.unpack_from("<I", reply, 14)[0]
        vendor.setdefault("v", value)
        if value != vendor["v"]:
            raise SystemExit("the vendor id changed")

    return timed(args.count, op)


def rest(args):
    url = args.target.removeprefix("http://")
    conn = http.client.HTTPConnection(url, timeout=5)
    # --floor: no slave behind it, only the transport and ecatd's HTTP stack.
    path = "/healthz" if args.floor else f"/api/v1/slaves/{args.slave}/coe/sdo/0x1018/1"

    def op():
        conn.request("GET", path)
        response = conn.getresponse()
        body = response.read()
        if response.status != 200 or not body or (args.floor and body != b"ok\n"):
            raise SystemExit(f"REST {response.status}: {body!r}")

    return timed(args.count, op)


def grpc_stubs(proto_dir):
    from grpc_tools import protoc

    out = tempfile.mkdtemp(prefix="ecatd-grpc-stubs-")
    files = [
        os.path.join("ecat", "v1", f)
        for f in sorted(os.listdir(os.path.join(proto_dir, "ecat", "v1")))
        if f.endswith(".proto")
    ]
    include = os.path.join(os.path.dirname(protoc.__file__), "_proto")
    code = protoc.main(
        ["protoc", f"-I{proto_dir}", f"-I{include}", f"--python_out={out}", f"--grpc_python_out={out}"]
        + files
    )
    if code != 0:
        raise SystemExit(f"grpc_tools.protoc failed ({code})")
    sys.path.insert(0, out)
    return out


def grpc_client(args):
    import shutil

    import grpc

    out = grpc_stubs(args.proto)
    try:
        from ecat.v1 import bus_pb2, bus_pb2_grpc, mailbox_pb2, mailbox_pb2_grpc

        channel = grpc.insecure_channel(args.target)
        if args.floor:
            # No slave behind it, only the transport and ecatd's HTTP/2 stack.
            bus = bus_pb2_grpc.BusServiceStub(channel)
            log_filter = bus_pb2.GetLogFilterRequest()

            def op():
                if not bus.GetLogFilter(log_filter, timeout=5).filter:
                    raise SystemExit("an empty log filter")

        else:
            stub = mailbox_pb2_grpc.CoeServiceStub(channel)
            request = mailbox_pb2.UploadRequest(slave=str(args.slave), index=0x1018, subindex=1)

            def op():
                answer = stub.Upload(request, timeout=5)
                if len(answer.data) != 4:
                    raise SystemExit(f"unexpected gRPC answer {answer}")

        result = timed(args.count, op)
        channel.close()
        return result
    finally:
        shutil.rmtree(out, ignore_errors=True)


def bringup(args):
    import pysoem

    master = pysoem.Master()
    master.open(args.target)
    try:
        t0 = time.perf_counter()
        found = master.config_init()
        t1 = time.perf_counter()
        if found == -4:
            # SOEM's EC_SLAVECOUNTEXCEEDED: more slaves than it was built for (EC_MAXSLAVE).
            raise SystemExit(f"SOEM refuses {args.slaves} slaves (EC_MAXSLAVE exceeded)")
        if found != args.slaves:
            raise SystemExit(f"config_init found {found} slaves, not {args.slaves}")
        master.config_map()
        if master.state_check(pysoem.SAFEOP_STATE, 5_000_000) != pysoem.SAFEOP_STATE:
            raise SystemExit("not every slave reached SAFEOP")
        t2 = time.perf_counter()
        master.send_processdata()
        master.receive_processdata(2000)
        master.state = pysoem.OP_STATE
        master.write_state()
        reached = 0
        for _ in range(2000):
            master.send_processdata()
            master.receive_processdata(2000)
            reached = master.state_check(pysoem.OP_STATE, 5000)
            if reached == pysoem.OP_STATE:
                break
        t3 = time.perf_counter()
        if reached != pysoem.OP_STATE:
            raise SystemExit("not every slave reached OP")
        master.state = pysoem.INIT_STATE
        master.write_state()
    finally:
        master.close()
    return {
        "init_ms": (t1 - t0) * 1e3,
        "map_safeop_ms": (t2 - t1) * 1e3,
        "op_ms": (t3 - t2) * 1e3,
        "total_ms": (t3 - t0) * 1e3,
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["raw", "gateway", "rest", "grpc", "bringup"])
    parser.add_argument("target")
    parser.add_argument("--count", type=int, default=2000)
    parser.add_argument("--station", type=int, default=1001)
    parser.add_argument("--slave", type=int, default=0)
    parser.add_argument("--floor", action="store_true", help="a call with no slave behind it")
    parser.add_argument("--slaves", type=int, default=0)
    parser.add_argument("--proto", default="proto")
    args = parser.parse_args()
    run = {"raw": raw, "gateway": gateway, "rest": rest, "grpc": grpc_client, "bringup": bringup}
    json.dump(run[args.mode](args), sys.stdout)
    print()


if __name__ == "__main__":
    main()
