"""``jax.distributed`` for real: two processes on localhost (CPU collectives) evaluate one
population and get what one process with the same two devices gets, bitwise (each device
holds the same rollouts in both cases), by direct calls and by the queue."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

WORKER = Path(__file__).with_name("distributed_worker.py")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def _env(**extra):
    """This environment without any inherited XLA_FLAGS, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    return {**env, **extra}


@pytest.mark.slow
def test_two_processes_equal_one(tmp_path):
    port = str(_free_port())
    procs = [
        subprocess.Popen(
            [sys.executable, str(WORKER), port, "2", str(i), str(tmp_path / f"p{i}.json")],
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for i in range(2)
    ]
    one = subprocess.run(
        [sys.executable, str(WORKER), "0", "1", "0", str(tmp_path / "one.json")],
        env=_env(XLA_FLAGS="--xla_force_host_platform_device_count=2"),
        capture_output=True,
        text=True,
        timeout=600,
    )
    logs = [p.communicate(timeout=600)[0] for p in procs]
    for p, log in zip(procs, logs, strict=True):
        assert p.returncode == 0, log[-3000:]
    assert one.returncode == 0, one.stderr[-3000:]
    docs = [json.loads((tmp_path / f"{n}.json").read_text()) for n in ("p0", "p1", "one")]
    assert [d["process_count"] for d in docs] == [2, 2, 1]
    assert all(d["devices"] == 2 for d in docs)
    for mode in ("direct", "queued"):
        assert docs[0][mode] == docs[1][mode] == docs[2][mode], mode
    assert docs[2]["direct"]["valid"].count(True) >= 4  # not a trivially equal all-fail batch
