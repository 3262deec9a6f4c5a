"""One XLA host device per core for the training command (jaxgait.core.host_devices)."""

import os
import subprocess
import sys

import pytest

from jaxgait.core import host_devices as hd


def test_requested_devices_reads_the_variable():
    assert hd.requested_devices({}) == hd.cpu_cores()
    assert hd.requested_devices({hd.ENV: "auto"}) == hd.cpu_cores()
    assert hd.requested_devices({hd.ENV: " 3 "}) == 3
    for bad in ("0", "-2", "two", "1.5"):
        with pytest.raises(ValueError, match=hd.ENV):
            hd.requested_devices({hd.ENV: bad})


def test_flag_added_only_where_it_can_act(monkeypatch):
    monkeypatch.setattr(hd, "backend_started", lambda: False)
    env = {hd.ENV: "4", "XLA_FLAGS": "--xla_cpu_foo=1"}
    assert hd.use_cpu_cores(env) == 4
    assert env["XLA_FLAGS"] == f"--xla_cpu_foo=1 {hd.FLAG}=4"
    assert hd.use_cpu_cores(env) is None  # already set: left alone
    assert env["XLA_FLAGS"].count(hd.FLAG) == 1
    one = {hd.ENV: "1"}
    assert hd.use_cpu_cores(one) is None and "XLA_FLAGS" not in one
    monkeypatch.setattr(hd, "backend_started", lambda: True)
    late = {hd.ENV: "4"}
    assert hd.use_cpu_cores(late) is None and "XLA_FLAGS" not in late  # too late: unchanged


def test_module_command_detection():
    assert hd.is_module_command(["python", "-m", "jaxgait.train", "exp3"], "jaxgait.train")
    assert hd.is_module_command(["python", "-X", "dev", "-m", "jaxgait.train"], "jaxgait.train")
    assert not hd.is_module_command(["python", "-m", "pytest"], "jaxgait.train")
    assert not hd.is_module_command(["python", "jaxgait.train"], "jaxgait.train")


def _devices_after(code: str, **env) -> int:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | env
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return int(out.stdout.strip().splitlines()[-1])


def test_a_fresh_process_gets_the_devices():
    code = (
        "from jaxgait.core import host_devices as h; h.use_cpu_cores(); "
        "import jax; print(jax.device_count())"
    )
    assert _devices_after(code, JAXGAIT_CPU_DEVICES="3") == 3
    # the Python API (importing jaxgait.train outside the command) keeps one device
    assert (
        _devices_after(
            "import jaxgait.train, jax; print(jax.device_count())", JAXGAIT_CPU_DEVICES="3"
        )
        == 1
    )


def test_only_the_command_sets_devices(monkeypatch):
    """``jaxgait train`` from the shell sets the devices; ``cli.main`` in a Python session
    (a notebook, a test) leaves them alone."""
    from jaxgait import cli

    calls = []
    monkeypatch.setattr(hd, "use_cpu_cores", lambda: calls.append(1))
    monkeypatch.setattr(cli, "main", lambda argv: 0)
    assert cli.console_main(["train", "--list"]) == 0 and calls == [1]
    assert cli.console_main(["list"]) == 0 and calls == [1]
