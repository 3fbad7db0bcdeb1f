"""nlo_lab.evaluation: the JSON contract, the table, and the command line's last line."""

from __future__ import annotations

import json

import pytest
import torch

import nlo_lab.evaluation.scores as scores
from nlo_lab.cli import main as cli_main
from nlo_lab.evaluation import JSON_KEYS, METHODS, BaselineSettings, Evaluation, SequenceScore, evaluate, format_table, to_json
from nlo_lab.model import encoder_input
from nlo_lab.training import SupervisedSettings, new_model, train_supervised_net

FAST = BaselineSettings(iterations=2, ik_iterations=3)


@pytest.fixture(scope="session")
def robot_clips(demonstration_from_robot, random_feasible_pose):
    def build(robot, n=2, frames=5):
        out = []
        for i in range(n):
            d = demonstration_from_robot(robot, random_feasible_pose(robot, frames, seed=10 + i))
            d.name = f"clip_{i}"
            out.append(d)
        return out

    return build


@pytest.fixture(scope="module")
def small(nao, random_feasible_pose, robot_clips):
    """Two short sequences, an untrained model and a tiny supervised network (no corpus, no checkpoint)."""
    demos = robot_clips(nao)
    torch.manual_seed(0)
    model = new_model(nao)
    x = torch.cat([encoder_input(d).node_features for d in demos])
    q = random_feasible_pose(nao, len(x), seed=1)
    net = train_supervised_net(nao, x, q, SupervisedSettings(epochs=1, hidden=(8,)))
    return demos, model, net


@pytest.fixture
def offline(monkeypatch, nao, small, robot_clips):
    """The command line on the small sequences: corpus, checkpoint and network patched in."""
    demos, model, net = small
    monkeypatch.setattr(scores, "sign_corpus", lambda split, seed=0: robot_clips(nao, n=3))
    monkeypatch.setattr(scores, "load_pretrained", lambda robot, checkpoint=None: model)
    monkeypatch.setattr(scores, "supervised_network", lambda robot, settings=None, **k: net)
    return demos


def test_json_has_exactly_the_contract_keys(nao, small):
    demos, model, net = small
    ev = evaluate(nao, demos, FAST, model=model, network=net, progress=False)
    out = json.loads(json.dumps(to_json(ev)))  # JSON-serialisable
    assert list(out) == ["methods"]
    assert set(out["methods"]) == set(METHODS)
    for name, m in out["methods"].items():
        assert set(m) == set(JSON_KEYS), name
        assert set(m["per_sequence"]) == {d.name for d in demos}
        per = list(m["per_sequence"].values())
        assert m["frechet_m"] == pytest.approx(sum(per) / len(per))
        assert all(v >= 0 for v in per)
        assert m["limit_violations"] == 0  # every method stays inside the limits
        assert isinstance(m["collision_sequences"], int) and 0 <= m["collision_sequences"] <= len(demos)
        assert m["seconds"] > 0


def test_methods_differ_where_they_should(nao, small):
    demos, model, net = small
    s = BaselineSettings(iterations=15, ik_iterations=40)
    ev = evaluate(nao, demos, s, methods=["encoder_only", "latent_encoder", "ik"], model=model, network=net, progress=False)
    # latent optimisation never ends above its own start (per-frame best is kept)
    for seq in ev.sequences:
        assert ev.scores["latent_encoder"][seq].objective <= ev.scores["encoder_only"][seq].objective + 1e-6
    # the targets come from the robot's own poses, so wrist IK tracks the wrists closely
    assert ev.mean("ik", "frechet_wrist_m") < ev.mean("encoder_only", "frechet_wrist_m")


def _score(frechet, collisions):
    return SequenceScore(frechet, frechet, frechet, 0.1, 1.0, collisions, 0, 2.0, 0.5, 10)


def test_table_marks_collision_sequences():
    ev = Evaluation(
        "nao",
        ["seq_a", "seq_b"],
        {"latent_encoder": {"seq_a": _score(0.1234, 0), "seq_b": _score(0.2, 3)}, "ik": {"seq_a": _score(0.3, 1), "seq_b": _score(0.4, 0)}},
    )
    table = format_table(ev)
    line_a = next(line for line in table.splitlines() if line.startswith("seq_a"))
    line_b = next(line for line in table.splitlines() if line.startswith("seq_b"))
    assert line_a.split()[1:] == ["0.1234", "0.3000*"]
    assert line_b.split()[1:] == ["0.2000*", "0.4000"]
    mean = next(line for line in table.splitlines() if line.startswith("mean"))
    assert mean.split()[-2:] == ["0.1617", "0.3500"]
    assert to_json(ev)["methods"]["latent_encoder"]["collision_sequences"] == 1
    assert "| seq_b | 0.2000* | 0.4000 |" in format_table(ev, markdown=True)


@pytest.mark.slow
def test_cli_json_last_line_is_the_contract(offline, capsys):
    status = cli_main(["evaluate", "--robot", "nao", "--split", "test", "--json", "--limit", "2"])
    out = capsys.readouterr().out.strip().splitlines()
    assert status == 0
    obj = json.loads(out[-1])
    assert set(obj) == {"methods"} and set(obj["methods"]) == set(METHODS)
    for m in obj["methods"].values():
        assert set(m) == set(JSON_KEYS)
        assert list(m["per_sequence"]) == ["clip_0", "clip_1"]  # --limit 2 of 3


def test_cli_table_without_json(offline, capsys):
    assert cli_main(["evaluate", "--robot", "nao", "--limit", "1"]) == 0
    out = capsys.readouterr().out
    assert "clip_0" in out and "clip_1" not in out
    for name in METHODS:
        assert name in out
    assert "mean [m]" in out and "wall time [s]" in out


def test_cli_unknown_robot_exits_2(capsys):
    assert cli_main(["evaluate", "--robot", "wall-e", "--json"]) == 2
    err = capsys.readouterr().err
    assert "wall-e" in err and "Traceback" not in err


def test_cli_limit_zero_exits_2(offline, capsys):
    assert cli_main(["evaluate", "--robot", "nao", "--limit", "0"]) == 2
    assert "--limit" in capsys.readouterr().err


def test_cli_methods_and_iters_choose_what_runs(offline, capsys, monkeypatch):
    seen = []
    real = scores.run_method
    def spy(name, robot, demo, settings, **k):
        seen.append((name, settings.iterations))
        return real(name, robot, demo, settings, **k)

    monkeypatch.setattr(scores, "run_method", spy)
    status = cli_main(["evaluate", "--robot", "nao", "--json", "--limit", "1", "--methods", "ik, joint_space", "--iters", "3", "--quiet"])
    obj = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert status == 0 and list(obj["methods"]) == ["ik", "joint_space"]
    assert seen == [("ik", 3), ("joint_space", 3)]


def test_cli_unknown_method_is_one_line_exit_2(offline, capsys):
    assert cli_main(["evaluate", "--robot", "nao", "--methods", "ik,telepathy"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "telepathy" in err and "Traceback" not in err
