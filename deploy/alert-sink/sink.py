"""The compose rig's webhook receiver: keeps, in memory, every JSON body POSTed to
/alerts (Alertmanager's webhook notifications) and answers GET /alerts with them as a JSON
array, oldest first. Nothing else: it exists so that deploy/test can see which alerts
Alertmanager delivered.

Usage: alert-sink [PORT]   (default 9095; listens on every address of its container)
"""

import json
import sys
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

# A notification larger than this is refused (413): the sink keeps everything in memory.
MAX_BODY = 1 << 20
# At most this many notifications are kept; the oldest go first.
MAX_KEPT = 1000

kept = []
lock = threading.Lock()


class Handler(BaseHTTPRequestHandler):
    def _answer(self, status, body=b"", kind="text/plain"):
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_POST(self):
        if self.path != "/alerts":
            return self._answer(404, b"not found\n")
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            return self._answer(411, b"length required\n")
        if length < 0 or length > MAX_BODY:
            return self._answer(413, b"too large\n")
        try:
            notification = json.loads(self.rfile.read(length))
        except ValueError:
            return self._answer(400, b"not JSON\n")
        with lock:
            kept.append(notification)
            del kept[:-MAX_KEPT]
        return self._answer(200, b"kept\n")

    def do_GET(self):
        if self.path == "/healthz":
            return self._answer(200, b"ok\n")
        if self.path != "/alerts":
            return self._answer(404, b"not found\n")
        with lock:
            body = json.dumps(kept).encode()
        return self._answer(200, body, "application/json")

    def log_message(self, fmt, *args):
        sys.stderr.write("alert-sink: %s %s\n" % (self.address_string(), fmt % args))


def main():
    port = int(sys.argv[1]) if len(sys.argv) > 1 else 9095
    ThreadingHTTPServer(("", port), Handler).serve_forever()


if __name__ == "__main__":
    main()
