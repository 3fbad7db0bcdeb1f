"""`nlo-lab lab` inside a running Jupyter (a hub, a kernel) and as root.

Inside a hub it copies the notebooks and says how to open them there in a few lines: it starts
no server (no exec, no process, no socket bound: each would fail the test). As root, without
--allow-root, it stops before any work with one line naming that flag; exit status 2.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys

import pytest

import nlo_lab.cli.lab as lab_cli
from nlo_lab.cli import main

HUB = {"JUPYTERHUB_USER": "learner", "JUPYTERHUB_SERVICE_PREFIX": "/user/learner/", "JUPYTERHUB_API_URL": "http://127.0.0.1:1/hub/api"}


@pytest.fixture
def plain_env(monkeypatch):
    """No Jupyter around this test (whatever runs it), and nothing may start a server."""
    for key in list(os.environ):
        if key.startswith(("JUPYTERHUB_", "JPY_")):
            monkeypatch.delenv(key)
    started = []

    def refuse(name):
        def call(*args, **kwargs):
            started.append((name, args))
            raise AssertionError(f"nlo-lab lab called {name}")
        return call

    monkeypatch.setattr(lab_cli.os, "execv", refuse("os.execv"))
    monkeypatch.setattr(subprocess, "Popen", refuse("subprocess.Popen"))
    monkeypatch.setattr(socket.socket, "bind", refuse("socket.bind"))
    monkeypatch.setattr(socket.socket, "listen", refuse("socket.listen"))
    return started


def _lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


@pytest.mark.parametrize("env", [HUB, {"JPY_SESSION_NAME": "/home/learner/x.ipynb"}], ids=["hub", "kernel"])
def test_inside_a_running_jupyter_it_copies_says_where_and_starts_nothing(plain_env, monkeypatch, capsys, tmp_path, env):
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    monkeypatch.setenv("JUPYTER_SERVER_ROOT", str(tmp_path))
    monkeypatch.setattr(os, "geteuid", lambda: 0, raising=False)  # even as root: nothing is started
    folder = tmp_path / "nlo_lab_notebooks"
    assert main(["lab", "--dir", str(folder)]) == 0
    assert plain_env == []
    out, err = capsys.readouterr()
    assert out.strip() == str(folder) and (folder / "01_robots_and_kinematics.ipynb").is_file()
    lines = _lines(err)
    assert 2 <= len(lines) <= 3, err
    assert "nlo_lab_notebooks/01_robots_and_kinematics.ipynb" in lines[1] and "none is started" in lines[1]
    if "JUPYTERHUB_SERVICE_PREFIX" in env:
        assert "/user/learner/lab/tree/nlo_lab_notebooks/01_robots_and_kinematics.ipynb" in lines[2]


def test_as_root_it_stops_in_one_line_naming_the_flag(plain_env, monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(os, "geteuid", lambda: 0, raising=False)
    folder = tmp_path / "nb"
    assert main(["lab", "--dir", str(folder)]) == 2
    (line,) = _lines(capsys.readouterr().err)
    assert line.startswith("nlo-lab: error:") and "root" in line and "--allow-root" in line
    assert not folder.exists() and plain_env == []  # stopped before any work


def test_allow_root_and_a_plain_user_start_jupyterlab_on_loopback(plain_env, monkeypatch, tmp_path):
    pytest.importorskip("jupyterlab")
    ran = []
    monkeypatch.setattr(lab_cli.os, "execv", lambda exe, cmd: ran.append(cmd))
    for uid, flags in ((0, ["--allow-root"]), (1000, [])):
        monkeypatch.setattr(os, "geteuid", lambda uid=uid: uid, raising=False)
        assert main(["lab", "--dir", str(tmp_path / "nb"), *flags]) == 0
    (as_root, as_user) = ran
    assert "--ip=127.0.0.1" in as_root and as_root[-1] == "--allow-root" and "--allow-root" not in as_user


def test_the_command_on_a_hub_returns_at_once(tmp_path):
    """The real command in a process of its own, as a learner types it in a hub's terminal: it ends by itself."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JUPYTERHUB_", "JPY_"))}
    env.update(HUB, JUPYTER_SERVER_ROOT=str(tmp_path))
    run = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "lab", "--dir", str(tmp_path / "nb")], env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout.strip() == str(tmp_path / "nb"), run.stderr
    assert len(_lines(run.stderr)) <= 3 and "Traceback" not in run.stderr


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="the real root path needs root")
def test_the_command_as_root_is_one_line_exit_2(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JUPYTERHUB_", "JPY_"))}
    run = subprocess.run([sys.executable, "-m", "nlo_lab.cli", "lab", "--dir", str(tmp_path / "nb")], env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and len(_lines(run.stderr)) == 1 and "--allow-root" in run.stderr, run.stderr
    assert not (tmp_path / "nb").exists()
