"""Running the server: the bind check (:func:`check_bind`: beyond this machine only with a token), a server in a
background thread (:class:`Running`: tests, notebooks, benchmarks) and :func:`serve`, what
``python -m jgrounding.serve`` runs."""

from __future__ import annotations

import ipaddress
import time

from jgrounding.serving.app import Policy, Server
from jgrounding.serving.protocol import WS_MAX_SIZE, Limits

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_bind(host: str, token: str | None) -> None:
    """Refuse to listen beyond this machine without a token clients must send."""
    if not is_loopback(host) and not token:
        raise ValueError(
            f"binding to {host!r} exposes the robot to the network; give --token (or JGROUNDING_TOKEN) so that "
            "clients must authenticate, or bind to 127.0.0.1 (the default)"
        )


class Running:
    """A server listening in a background thread (tests, benchmarks): ``.url``, ``.stop()``."""

    def __init__(self, server: Server, host: str = DEFAULT_HOST, port: int = 0, log_level: str = "warning"):
        import socket
        import threading

        import uvicorn

        check_bind(host, server.token)
        self.server = server
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.host, self.port = self.sock.getsockname()[:2]
        config = uvicorn.Config(server.app(), log_level=log_level, ws_max_size=WS_MAX_SIZE, lifespan="off")
        self.uvicorn = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.uvicorn.run, kwargs={"sockets": [self.sock]}, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 30
        while not self.uvicorn.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("the server did not start")
            time.sleep(0.01)

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}/ws"

    @property
    def http(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def stop(self) -> None:
        self.uvicorn.should_exit = True
        self.thread.join(timeout=10)
        self.sock.close()


def serve(
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    *,
    checkpoint=None,
    token: str | None = None,
    limits: Limits = Limits(),
    allow_library_mismatch: bool = False,
    log_level: str = "info",
    trunk: str | None = None,
) -> None:
    """Load the model once and serve until interrupted (what ``python -m jgrounding.serve`` runs); ``trunk``: the
    MJCF simulated (screening, backbones, the stream's trunk; None: the shipped trunk)."""
    import uvicorn

    check_bind(host, token)
    t0 = time.perf_counter()
    policy = Policy(checkpoint, allow_library_mismatch, trunk=trunk)
    print(
        f"jgrounding serve: model {policy.model_info['checkpoint']} (library {policy.model_info['library_version']}) "
        f"loaded and compiled in {time.perf_counter() - t0:.1f} s",
        flush=True,
    )
    server = Server(policy, limits, token)
    shown = "localhost" if host == DEFAULT_HOST else host
    print(f"  page:      http://{shown}:{port}/" + ("?token=..." if token else ""), flush=True)
    print(f"  websocket: ws://{shown}:{port}/ws  (python -m jgrounding.client --url ws://{shown}:{port}/ws ...)")
    uvicorn.run(server.app(), host=host, port=port, log_level=log_level, ws_max_size=WS_MAX_SIZE, lifespan="off")
