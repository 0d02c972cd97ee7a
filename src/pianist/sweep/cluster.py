"""A Ray cluster of several nodes on this machine: to try ``pianist sweep --address`` (and to
test it) without a second machine.

:func:`local_cluster` starts a head (``ray start --head``) and more nodes joined to it
(``ray start --address``), each with its own CPUs and temporary folder, all on loopback
addresses, with token authentication under a token of their own; it yields the address and
the environment a driver needs to join (``RAY_AUTH_MODE=token`` and the token), and stops
exactly the processes it started (never ``ray stop``, which stops every Ray on the machine).
"""

from __future__ import annotations

import logging
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

#: The head's address: a loopback address other than 127.0.0.1, which Ray would replace by
#: the machine's network address; the other nodes then see themselves as 127.0.0.1.
HEAD_IP = "127.0.0.2"
NODE_OBJECT_STORE_BYTES = 100_000_000


@dataclass(frozen=True)
class LocalCluster:
    """A running cluster: ``address`` for ``--address``, ``env`` for the driver's process."""

    address: str
    env: dict[str, str]
    logs: list[Path]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ray_command() -> str:
    ray = Path(sys.executable).parent / "ray"
    return str(ray) if ray.exists() else "ray"


def _stop(node: subprocess.Popen[bytes]) -> None:
    """Stop one ``ray start --block`` node: SIGTERM makes it drain and stop its processes; if
    that hangs, its process group (only the processes it started) is killed."""
    if node.poll() is None:
        node.send_signal(signal.SIGTERM)
        try:
            node.wait(timeout=40)
            return
        except subprocess.TimeoutExpired:
            pass
    try:
        os.killpg(node.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    node.wait(timeout=10)


def _wait_for_port(port: int, head: subprocess.Popen[bytes], log: Path, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if head.poll() is not None:
            raise RuntimeError(f"the Ray head exited: {log.read_text()[-1500:]}")
        try:
            with socket.create_connection((HEAD_IP, port), timeout=1):
                return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"the Ray head did not listen on {HEAD_IP}:{port} in {timeout_s:g} s")


_WAIT_FOR_NODES = """
import logging, sys, time
import ray
ray.init(address=sys.argv[1], log_to_driver=False, logging_level=logging.ERROR)
deadline = time.monotonic() + float(sys.argv[3])
while sum(n["Alive"] for n in ray.nodes()) < int(sys.argv[2]):
    if time.monotonic() > deadline:
        sys.exit("nodes alive: %d" % sum(n["Alive"] for n in ray.nodes()))
    time.sleep(0.2)
"""


@contextmanager
def local_cluster(
    num_nodes: int = 2, cpus_per_node: int = 1, timeout_s: float = 90.0
) -> Iterator[LocalCluster]:
    """Start a head and ``num_nodes - 1`` more nodes on this machine; stop them on exit.

    Args:
        num_nodes: nodes in all, the head included (>= 1).
        cpus_per_node: CPUs each node offers.
        timeout_s: how long the nodes may take to start and join.
    Yields:
        The cluster, once every node has joined.
    Raises:
        RuntimeError: a node did not start or join in time (its log's end in the message).
    """
    if num_nodes < 1 or cpus_per_node < 1:
        raise ValueError("a cluster needs at least one node of at least one CPU")
    port = _free_port()
    address = f"{HEAD_IP}:{port}"
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS",)}
    env.update(
        RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(16), RAY_USAGE_STATS_ENABLED="0"
    )
    env.pop("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", None)  # a joined node needs cluster mode
    common = [
        f"--num-cpus={cpus_per_node}",
        f"--object-store-memory={NODE_OBJECT_STORE_BYTES}",
        "--disable-usage-stats",
        "--block",
    ]
    # Ray's socket paths must stay under 108 bytes: a short temporary folder.
    root = Path(tempfile.mkdtemp(prefix="pianist-ray-"))
    nodes: list[subprocess.Popen[bytes]] = []
    logs: list[Path] = []

    def start(args: list[str], name: str) -> subprocess.Popen[bytes]:
        (root / name).mkdir()
        log = root / f"{name}.log"
        logs.append(log)
        with open(log, "wb") as stream:
            node = subprocess.Popen(
                [_ray_command(), "start", *args, f"--temp-dir={root / name}", *common],
                env=env,
                stdout=stream,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # its own process group, to stop only its processes
            )
        nodes.append(node)
        return node

    try:
        head = ["--head", f"--port={port}", f"--node-ip-address={HEAD_IP}"]
        start([*head, "--include-dashboard=false"], "head")
        _wait_for_port(port, nodes[0], logs[0], timeout_s)
        for index in range(1, num_nodes):
            start([f"--address={address}"], f"node{index}")
        joined = subprocess.run(
            [sys.executable, "-c", _WAIT_FOR_NODES, address, str(num_nodes), str(timeout_s)],
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout_s + 30,
        )
        if joined.returncode != 0:
            tail = logs[-1].read_text()[-1500:]
            raise RuntimeError(f"the nodes did not join: {joined.stderr[-1500:]} {tail}")
        yield LocalCluster(address, env, logs)
    finally:
        for node in reversed(nodes):
            try:
                _stop(node)
            except Exception as exc:  # noqa: BLE001 - stop the others all the same
                logging.getLogger(__name__).warning("stopping a Ray node: %s", exc)
        shutil.rmtree(root, ignore_errors=True)
