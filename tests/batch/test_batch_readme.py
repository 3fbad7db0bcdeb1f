"""The README's three ways to run ``nlo-lab batch`` say what the code does: the flags its commands use
exist, and the SLURM example (which cannot run here: no SLURM) is valid Python calling ``retarget_many``
with its real parameters; with dask-jobqueue installed, the job script it makes asks for one core and
one thread per job."""

from __future__ import annotations

import argparse
import ast
import inspect
import re
import shlex
from pathlib import Path

import pytest

from nlo_lab.batch import retarget_many
from nlo_lab.cli import batch as batch_command

README = Path(__file__).resolve().parents[2] / "README.md"


def _batch_section() -> str:
    text = README.read_text(encoding="utf-8")
    start = text.index("### A whole corpus: `nlo-lab batch`")
    return text[start:text.index("\n### ", start + 1)]


def _slurm_example() -> ast.Module:
    section = _batch_section()
    slurm = section[section.index("**A SLURM cluster**"):]
    code = re.search(r"```python\n(.*?)```", slurm, re.S)
    assert code, "the SLURM example's python block"
    lines = code.group(1).splitlines()
    indent = min(len(line) - len(line.lstrip()) for line in lines if line.strip())
    return ast.parse("\n".join(line[indent:] for line in lines))


def _calls(tree: ast.Module, name: str) -> list[ast.Call]:
    return [node for node in ast.walk(tree) if isinstance(node, ast.Call)
            and (getattr(node.func, "id", None) == name or getattr(node.func, "attr", None) == name)]


def test_the_flags_of_the_readmes_batch_commands_are_the_commands_flags():
    batch = batch_command.add_parser(argparse.ArgumentParser(prog="nlo-lab").add_subparsers())
    # the parser's own option strings (its help text may wrap a flag at its hyphen)
    known = {flag for action in batch._actions for flag in action.option_strings if flag.startswith("--")}
    assert {"--robot", "--out", "--workers", "--scheduler", "--quiet"} <= known
    section = _batch_section()
    commands = [line.strip() for line in section.splitlines() if line.strip().startswith("nlo-lab batch ")]
    assert len(commands) >= 2  # the first example and the one on a running scheduler
    used = {word for command in commands for word in shlex.split(command, comments=True) if word.startswith("--")}
    assert used and used <= known, used - known
    usage = README.read_text(encoding="utf-8")
    usage = usage[usage.index("nlo-lab batch    INPUT"):]
    usage = usage[:usage.index("\nnlo-lab ", 1)]
    listed = set(re.findall(r"--[a-z-]+", usage))
    assert listed == known - {"--help"}, listed ^ (known - {"--help"})  # the usage line lists every flag


def test_the_slurm_example_calls_retarget_many_with_its_real_parameters():
    tree = _slurm_example()
    (call,) = _calls(tree, "retarget_many")
    parameters = inspect.signature(retarget_many).parameters
    assert {k.arg for k in call.keywords} <= set(parameters)
    assert len(call.args) == 3 and list(parameters)[:3] == ["inputs", "robot", "out"]
    (adapt,) = _calls(tree, "adapt")
    assert {k.arg for k in adapt.keywords} == {"minimum_jobs", "maximum_jobs"}


def test_the_slurm_examples_job_script_asks_one_core_and_one_thread():
    jobqueue = pytest.importorskip("dask_jobqueue.slurm", reason="dask-jobqueue is not installed (pip install dask-jobqueue)")
    (cluster,) = _calls(_slurm_example(), "SLURMCluster")
    options = {k.arg: ast.literal_eval(k.value) for k in cluster.keywords}
    script = jobqueue.SLURMJob(scheduler="tcp://127.0.0.1:8786", name="nlo-lab", **options).job_script()  # no scheduler starts
    for line in ("#SBATCH -n 1", "#SBATCH --cpus-per-task=1", "#SBATCH --mem=4G", "#SBATCH -t 02:00:00", "export NLO_LAB_THREADS=1"):
        assert line in script.splitlines(), script
    worker = script.splitlines()[-1]
    assert "dask_worker tcp://127.0.0.1:8786" in worker and worker.count("--nthreads 1") == 1, worker


def test_retarget_many_defaults_are_the_batch_commands():
    """The README: ``retarget_many(...)`` "does the same" as ``nlo-lab batch``: the same defaults (the latent
    budget was once 100 in Python and 40 on the command line)."""
    import dataclasses

    from nlo_lab.batch import BatchSettings
    from nlo_lab.cli.flags import hand_settings
    from nlo_lab.settings import LATENT_ITERATIONS

    parser = argparse.ArgumentParser(prog="nlo-lab")
    batch_command.add_parser(parser.add_subparsers())
    args = parser.parse_args(["batch", "in", "--robot", "yumi", "--out", "out"])
    command = {"init": args.init, "iterations": args.iters, "seed": args.seed, "viewer": args.viewer, **hand_settings(args)}
    library = {k: p.default for k, p in inspect.signature(retarget_many).parameters.items() if k in command}
    fields = {f.name: f.default for f in dataclasses.fields(BatchSettings) if f.name in command}
    assert library == command == fields and command["iterations"] == LATENT_ITERATIONS
