"""nlo-lab lab's decisions, as functions: inside a running Jupyter, as root."""

from __future__ import annotations

from pathlib import Path

from nlo_lab.lab import lab_command, open_hint, root_refusal, running_jupyter

HUB = {"JUPYTERHUB_USER": "learner", "JUPYTERHUB_SERVICE_PREFIX": "/user/learner/", "JUPYTERHUB_API_URL": "http://hub:8081/hub/api"}


def test_a_hub_or_a_kernel_is_a_running_jupyter():
    assert running_jupyter(HUB) == "JupyterHub"
    assert running_jupyter({"JPY_SESSION_NAME": "/home/me/x.ipynb"}) == "Jupyter"  # `!nlo-lab lab` in a cell
    assert running_jupyter({"JPY_PARENT_PID": "123"}) == "Jupyter"
    assert running_jupyter({"HOME": "/home/me", "JUPYTERHUB_USER": ""}) is None  # an empty variable says nothing
    assert running_jupyter({}) is None


def test_the_hint_names_the_file_browser_path_and_the_hub_address(tmp_path):
    folder = tmp_path / "nlo_lab_notebooks"
    lines = open_hint(folder, "01_robots_and_kinematics.ipynb", {**HUB, "JUPYTER_SERVER_ROOT": str(tmp_path)})
    assert lines == [
        "a Jupyter is running here, so none is started: open nlo_lab_notebooks/01_robots_and_kinematics.ipynb in its file browser",
        "or at /user/learner/lab/tree/nlo_lab_notebooks/01_robots_and_kinematics.ipynb after your hub's address",
    ]
    # without a hub prefix: the file browser only; outside the server's root: where to copy them instead
    assert len(open_hint(folder, "01.ipynb", {"JUPYTER_SERVER_ROOT": str(tmp_path)})) == 1
    outside = open_hint(Path("/opt/elsewhere"), "01.ipynb", {"JUPYTER_SERVER_ROOT": str(tmp_path)})
    assert "outside the running Jupyter's folder" in outside[0] and str(tmp_path / "nlo_lab_notebooks") in outside[1]


def test_root_is_refused_with_the_flag_that_overrides_it(tmp_path):
    why = root_refusal(0)
    assert "root" in why and "--allow-root" in why and "\n" not in why
    assert root_refusal(1000) is None
    assert lab_command(tmp_path, 8888, allow_root=True)[-1] == "--allow-root"
    assert "--allow-root" not in lab_command(tmp_path, 8888)
