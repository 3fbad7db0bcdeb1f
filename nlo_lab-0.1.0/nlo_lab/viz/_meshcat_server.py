"""meshcat's ZMQ + web server bound to 127.0.0.1 only, and tied to its owner's life.

meshcat-python's own server listens on every interface. This launcher reuses
its request handling (``ZMQWebSocketBridge``) but binds both the ZMQ socket and
the web server to loopback on free ports, prints ``zmq_url=`` and ``web_url=``
lines like meshcat's server, and exits as soon as the owner process is gone
(checked every 0.5 s), so that a kernel killed with SIGKILL leaves no server
behind.

Run: ``python -m nlo_lab.viz._meshcat_server --parent-pid PID``.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time

import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import zmq
from meshcat.servers.tree import SceneTree
from meshcat.servers.zmqserver import ZMQWebSocketBridge
from zmq.eventloop.zmqstream import ZMQStream

HOST = "127.0.0.1"


class LoopbackBridge(ZMQWebSocketBridge):
    """meshcat's bridge with both sockets on 127.0.0.1 (ports chosen by the OS)."""

    def __init__(self) -> None:  # replaces the parent's, which listens on all interfaces
        self.host = HOST
        self.websocket_pool = set()
        self.app = self.make_app()
        self.ioloop = tornado.ioloop.IOLoop.current()
        self.zmq_socket = self.context.socket(zmq.REP)
        zmq_port = self.zmq_socket.bind_to_random_port(f"tcp://{HOST}")
        self.zmq_url = f"tcp://{HOST}:{zmq_port}"
        self.zmq_stream = ZMQStream(self.zmq_socket)
        self.zmq_stream.on_recv(self.handle_zmq)
        sockets = tornado.netutil.bind_sockets(0, address=HOST, family=__import__("socket").AF_INET)
        self.http_server = tornado.httpserver.HTTPServer(self.app)
        self.http_server.add_sockets(sockets)
        self.fileserver_port = sockets[0].getsockname()[1]
        self.web_url = f"http://{HOST}:{self.fileserver_port}/static/"
        self.tree = SceneTree()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _watch_parent(parent_pid: int, interval: float = 0.5) -> None:
    """Exit the whole process once the owner is gone (re-parented or no such pid)."""
    while True:
        if os.getppid() != parent_pid or not _alive(parent_pid):
            os._exit(0)
        time.sleep(interval)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="meshcat server on 127.0.0.1 that exits with its owner")
    parser.add_argument("--parent-pid", type=int, required=True, help="the owner's pid; the server exits when it is gone")
    args = parser.parse_args(argv)
    threading.Thread(target=_watch_parent, args=(args.parent_pid,), daemon=True).start()
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))
    bridge = LoopbackBridge()
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    # Nobody reads our stdout after the two lines: send later prints to /dev/null so a full pipe never blocks us.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
