"""The method and its baselines behind one interface (paper, "Comparative Study").

Every method is a function ``method(robot, demo, settings=None, **context) ->
MethodResult`` that turns a human :class:`~nlo_lab.human.Demonstration` into
joint angles ``(T, n)`` inside the limits, and measures its own wall time (from
the demonstration to the angles: targets, mapping and features included;
training of a network excluded). Two modes (:data:`EVALUATION_MODES`,
``BaselineSettings.mode``) give the paper's Table I twice:

* ``"robot-ready"`` (the default): the objective and pipeline of ``nlo-lab retarget`` as
  shipped: the smoothness term (``LossWeights.smooth``) and warm start along the
  sequence, and the latent methods' output retimed to the joint velocity limits.
* ``"paper"``: the paper's objective (no smoothness term, frames independent, no hand terms) and no
  retiming.

The methods:

* ``latent_encoder``: the method: encoder initialisation + latent optimisation.
* ``encoder_only``: the encoder's latent decoded, no optimisation (the paper's 'Init').
* ``latent_random``: latent optimisation from ``N(0, random_sigma²)``.
* ``joint_space``: Adam on the angles themselves, same objective, clamped to the limits,
  from the robot's neutral pose (:func:`nlo_lab.inference.optimize_joints`).
* ``nn_supervised``: a feed-forward network from the human node features to the
  angles, trained supervised on joint-space optimisation results over the
  training split (the paper's 'NN'); trained once per settings, cached in memory
  and under the user cache folder (:func:`nlo_lab.training.supervised_network`).
* ``ik``: damped least squares on the two wrist positions only (the human
  wrists mapped into the robot frame, :func:`nlo_lab.human.map_to_robot`),
  limits by clamping after every step; fingers stay at the neutral pose.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.human import map_to_robot, node_features
from nlo_lab.inference import JointOptimizeSettings, OptimizeSettings, optimize_joints, retime_times
from nlo_lab.objective import LossWeights, objective, targets_from_demonstration
from nlo_lab.pipeline import RetargetConfig
from nlo_lab.settings import (
    ITERATIONS_RANGE,
    PATIENCE_RANGE,
    RATE_RANGE,
    SEED_RANGE,
    check_choice,
    check_int,
    check_range,
    validate_fields,
)
from nlo_lab.training import SupervisedNet, SupervisedSettings, supervised_network

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.model import RetargetModel
    from nlo_lab.robot import Robot

__all__ = [
    "METHODS",
    "LATENT_METHODS",
    "EVALUATION_MODES",
    "BaselineSettings",
    "MethodResult",
    "latent_encoder",
    "encoder_only",
    "latent_random",
    "joint_space",
    "nn_supervised",
    "ik",
    "ik_wrists",
    "wrist_positions",
    "run_method",
    "mean_objective",
]

METHODS = ("latent_encoder", "encoder_only", "latent_random", "joint_space", "nn_supervised", "ik")
LATENT_METHODS = ("latent_encoder", "encoder_only", "latent_random")  # need a trained model
EVALUATION_MODES = ("robot-ready", "paper")  # module docstring


@dataclass(frozen=True)
class BaselineSettings:
    """Settings shared by the methods (override with ``dataclasses.replace``).

    Attributes:
        iterations: the budget of the latent methods and of ``joint_space`` (the same for all); None: each
            method's default: in robot-ready mode the pipeline's (``OptimizeSettings()``: 40 Rprop steps on a
            sequence), in paper mode the paper's 100 Adam steps (``OptimizeSettings.paper()``); ``joint_space``
            100 Adam steps (``JointOptimizeSettings()``).
        patience: Adam's early stop after this many evaluations without improvement.
        random_sigma: σ of ``latent_random``'s start ``N(0, σ²)`` (1 = the latent prior).
        seed: seed of the random initialisation.
        joint_lr: Adam step size of ``joint_space`` [rad].
        ik_iterations: damped-least-squares steps of ``ik``.
        ik_damping: λ of ``ik`` [m]: ``dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e``.
        ik_tolerance: ``ik`` stops when every wrist error is below this [m].
        supervised: :class:`SupervisedSettings` of ``nn_supervised``.
        mode: ``"robot-ready"`` (the shipped defaults: smoothness term, warm start, the latent
            methods retimed) or ``"paper"`` (the paper's objective, no smoothness term, no
            retiming); see the module docstring.
        weights: the objective of the latent methods and ``joint_space``; None: the mode's
            (``LossWeights()``, in paper mode with ``smooth=0`` and without our hand terms
            ``tip``, ``thumb``, ``pinch``).
    """

    iterations: int | None = None
    patience: int = 5
    random_sigma: float = 1.0
    seed: int = 0
    joint_lr: float = 0.05
    ik_iterations: int = 50
    ik_damping: float = 0.05
    ik_tolerance: float = 1e-4
    supervised: SupervisedSettings = field(default_factory=SupervisedSettings)
    mode: str = "robot-ready"
    weights: LossWeights | None = None

    def __post_init__(self) -> None:
        check_choice("evaluation mode", self.mode, EVALUATION_MODES)
        if self.weights is not None and not isinstance(self.weights, LossWeights):
            raise SettingsError(f"weights must be a LossWeights, got {type(self.weights).__name__}")
        validate_fields(self, lambda name, v: v if v is None and name == "iterations" else check_int(name, v, *ITERATIONS_RANGE),
                        names=("iterations", "ik_iterations"))
        validate_fields(self, lambda name, v: check_int(name, v, *SEED_RANGE), names=("seed",))
        validate_fields(self, lambda name, v: check_int(name, v, *PATIENCE_RANGE), names=("patience",))
        validate_fields(self, lambda name, v: check_range(name, v, *RATE_RANGE),
                        names=("random_sigma", "joint_lr", "ik_damping", "ik_tolerance"))
        if not isinstance(self.supervised, SupervisedSettings):
            raise SettingsError(f"supervised must be a SupervisedSettings, got {type(self.supervised).__name__}")

    @property
    def loss_weights(self) -> LossWeights:
        """The objective's weights: ``weights``, else the mode's (paper: no smoothness term, no hand terms)."""
        if self.weights is not None:
            return self.weights
        return LossWeights.paper() if self.mode == "paper" else LossWeights()

    @property
    def latent_iterations(self) -> int:
        """The latent methods' budget: ``iterations``, else the mode's (robot-ready: the pipeline's, paper: the paper's)."""
        if self.iterations is not None:
            return self.iterations
        return OptimizeSettings.paper().iterations if self.mode == "paper" else OptimizeSettings().iterations

    @property
    def joint_iterations(self) -> int:
        """``joint_space``'s budget: ``iterations``, else :class:`JointOptimizeSettings`' default."""
        return self.iterations if self.iterations is not None else JointOptimizeSettings().iterations

    @property
    def retime(self) -> bool:
        """Whether the latent methods' output is retimed (robot-ready mode)."""
        return self.mode == "robot-ready"


@dataclass
class MethodResult:
    """What every method returns.

    Attributes:
        method: the method's name (one of :data:`METHODS`).
        angles: ``(T, n)`` float64 joint angles [rad], inside the limits.
        seconds: wall time from the demonstration to the angles [s].
        history: mean loss per iteration where the method iterates (else empty).
        iterations: iterations taken.
        times: ``(T,)`` when each frame plays [s] where the method retimed its output
            (robot-ready mode, latent methods); None: frames 1/fps apart.
    """

    method: str
    angles: np.ndarray
    seconds: float
    history: list[float] = field(default_factory=list)
    iterations: int = 0
    times: np.ndarray | None = None


def _numpy(q: torch.Tensor) -> np.ndarray:
    return q.detach().cpu().double().numpy()


def _latent(name: str, robot, demo, settings: BaselineSettings, model, init: str, iterations: int) -> MethodResult:
    """The retargeting pipeline's optimisation (:class:`~nlo_lab.pipeline.RetargetConfig`) with the
    evaluation's fixed budget and the mode's weights, the whole sequence as one batch; retimed
    to the velocity limits in robot-ready mode (as :meth:`~nlo_lab.pipeline.Retargeter.__call__` does). The
    pipeline's hand stage runs in robot-ready mode after an optimisation (not in paper mode, not for 'Init')."""
    hand = OptimizeSettings.hand_iterations if settings.mode == "robot-ready" and iterations > 0 else 0
    stepper = "adam" if settings.mode == "paper" else None  # paper: the paper's Adam; robot-ready: the pipeline's rule
    opt = OptimizeSettings(init=init, iterations=iterations, patience=settings.patience, latent_sigma=settings.random_sigma, seed=settings.seed,
                           hand_iterations=hand, stepper=stepper)
    retargeter = RetargetConfig(robot, opt, settings.loss_weights, model=model, chunk_frames=None, retime=settings.retime).build()
    start = time.perf_counter()
    r = retargeter.optimize(retargeter.inputs(demo))
    angles = _numpy(r.q)
    times = retime_times(angles, demo.fps, robot.velocity_limits.double().numpy()) if settings.retime else None
    return MethodResult(name, angles, time.perf_counter() - start, list(r.history), r.iterations, times)


def latent_encoder(robot: Robot, demo, settings: BaselineSettings | None = None, *, model: RetargetModel | None = None, **_) -> MethodResult:
    """The method: encoder initialisation, then ``settings.latent_iterations`` latent steps.

    Args:
        robot: a loaded robot.
        demo: the human demonstration (T frames).
        settings: :class:`BaselineSettings`.
        model: the robot's :class:`~nlo_lab.model.RetargetModel` (default: the shipped checkpoint).
    """
    s = settings or BaselineSettings()
    return _latent("latent_encoder", robot, demo, s, model, "encoder", s.latent_iterations)


def encoder_only(robot: Robot, demo, settings: BaselineSettings | None = None, *, model: RetargetModel | None = None, **_) -> MethodResult:
    """The encoder's latent decoded, no optimisation (the paper's 'Init'). Args as :func:`latent_encoder`."""
    s = settings or BaselineSettings()
    return _latent("encoder_only", robot, demo, s, model, "encoder", 0)


def latent_random(robot: Robot, demo, settings: BaselineSettings | None = None, *, model: RetargetModel | None = None, **_) -> MethodResult:
    """Latent optimisation from ``N(0, settings.random_sigma²)``. Args as :func:`latent_encoder`."""
    s = settings or BaselineSettings()
    return _latent("latent_random", robot, demo, s, model, "random", s.latent_iterations)


def joint_space(robot: Robot, demo, settings: BaselineSettings | None = None, **_) -> MethodResult:
    """Adam on the angles from the robot's neutral pose (``JointOptimizeSettings`` default), the mode's objective, clamped to the limits."""
    s = settings or BaselineSettings()
    start = time.perf_counter()
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    r = optimize_joints(robot, targets, JointOptimizeSettings(iterations=s.joint_iterations, patience=s.patience, lr=s.joint_lr), fast=True,
                        weights=s.loss_weights)
    return MethodResult("joint_space", _numpy(r.q), time.perf_counter() - start, list(r.history), r.iterations)


# ---------------------------------------------------------------------- inverse kinematics
def wrist_positions(robot: Robot, q: torch.Tensor) -> torch.Tensor:
    """``q (B, n)`` -> ``(B, 2, 3)`` wrist link positions (left, right) in the robot frame [m]."""
    poses = robot.forward_kinematics(q)
    return torch.stack([poses[robot.arm(side).wrist][..., :3, 3] for side in ("left", "right")], dim=-2)


def ik_wrists(
    robot: Robot,
    wrists: torch.Tensor,
    mask: torch.Tensor | None = None,
    *,
    q0: torch.Tensor | None = None,
    iterations: int = 50,
    damping: float = 0.05,
    tolerance: float = 1e-4,
    max_error: float = 0.1,
) -> tuple[torch.Tensor, int]:
    """Damped least squares on the two wrist positions, batched over frames.

    ``dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e`` with ``J (B, 6, n)`` the autograd Jacobian of
    both wrist positions and ``e`` the position error; after every step the
    angles are clamped into the limits.

    Args:
        robot: a loaded robot.
        wrists: ``(B, 2, 3)`` target wrist positions (left, right) [m].
        mask: ``(B, 2)`` bool: which targets count (a masked wrist has zero error).
        q0: ``(B, n)`` or ``(n,)`` start angles (default ``robot.neutral_q``).
        iterations: maximum steps.
        damping: λ [m].
        tolerance: stop when every counted wrist error is below this [m].
        max_error: the error of a wrist is shortened to at most this per step [m].

    Returns:
        ``q (B, n)`` inside the limits and the number of steps taken.
    """
    lo, hi = robot.lower_limits, robot.upper_limits
    B = wrists.shape[0]
    wrists = wrists.to(dtype=lo.dtype, device=lo.device)
    if mask is None:
        mask = torch.isfinite(wrists).all(-1)
    mask = mask.to(device=lo.device)
    target = torch.where(mask[..., None], torch.nan_to_num(wrists), torch.zeros_like(wrists))
    q = (robot.neutral_q if q0 is None else q0).to(dtype=lo.dtype, device=lo.device).expand(B, -1).clone()
    q = torch.maximum(torch.minimum(q, hi), lo)
    eye = torch.eye(6, dtype=lo.dtype, device=lo.device)
    steps = 0
    for _ in range(iterations):
        x = q.detach().requires_grad_(True)
        p = wrist_positions(robot, x).reshape(B, 6)  # (B, 6) [m]
        err = (target.reshape(B, 6) - p.detach()) * mask.repeat_interleave(3, dim=1)  # (B, 6)
        if float(err.view(B, 2, 3).norm(dim=-1).max()) < tolerance:
            break
        # Clamp the error per wrist (Buss's "clamping the target distance"): far targets
        # otherwise give huge steps that bounce off the limits.
        e3 = err.view(B, 2, 3)
        err = (e3 * (max_error / e3.norm(dim=-1, keepdim=True).clamp_min(max_error))).reshape(B, 6)
        rows = [torch.autograd.grad(p[:, k].sum(), x, retain_graph=k < 5)[0] for k in range(6)]  # frames are independent
        J = torch.stack(rows, dim=1) * mask.repeat_interleave(3, dim=1)[..., None]  # (B, 6, n)
        JJt = J @ J.transpose(1, 2) + (damping**2) * eye
        dq = (J.transpose(1, 2) @ torch.linalg.solve(JJt, err[..., None]))[..., 0]  # (B, n)
        q = torch.maximum(torch.minimum(q + dq, hi), lo)
        steps += 1
    return q.detach(), steps


def ik(robot: Robot, demo, settings: BaselineSettings | None = None, **_) -> MethodResult:
    """Inverse kinematics of the wrists only: the human wrists mapped into the robot
    frame (:func:`nlo_lab.human.map_to_robot`), damped least squares with clamping
    (:func:`ik_wrists`), every frame from the neutral pose."""
    s = settings or BaselineSettings()
    start = time.perf_counter()
    mapped = map_to_robot(demo, robot)[:, :, 2]  # (T, 2, 3) wrists [m], NaN where masked
    wrists = torch.as_tensor(mapped, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    q, steps = ik_wrists(robot, wrists, iterations=s.ik_iterations, damping=s.ik_damping, tolerance=s.ik_tolerance)
    return MethodResult("ik", _numpy(q), time.perf_counter() - start, [], steps)


def nn_supervised(robot: Robot, demo, settings: BaselineSettings | None = None, *, network: SupervisedNet | None = None, **_) -> MethodResult:
    """The paper's 'NN': one forward pass of :func:`supervised_network` per frame.

    Args:
        network: a trained :class:`SupervisedNet` (default: :func:`supervised_network`
            with ``settings.supervised``; training time is not part of ``seconds``).
    """
    s = settings or BaselineSettings()
    net = network if network is not None else supervised_network(robot, s.supervised)
    start = time.perf_counter()
    x = torch.as_tensor(np.nan_to_num(node_features(demo)), dtype=torch.float32)
    with torch.no_grad():
        q = net(x)
    q = torch.maximum(torch.minimum(q.double(), robot.upper_limits.double().cpu()), robot.lower_limits.double().cpu())  # round-off of float32
    return MethodResult("nn_supervised", q.numpy(), time.perf_counter() - start)


_FUNCTIONS: dict[str, Callable[..., MethodResult]] = {
    "latent_encoder": latent_encoder,
    "encoder_only": encoder_only,
    "latent_random": latent_random,
    "joint_space": joint_space,
    "nn_supervised": nn_supervised,
    "ik": ik,
}


def run_method(name: str, robot: Robot, demo, settings: BaselineSettings | None = None, *, model: RetargetModel | None = None, network=None) -> MethodResult:
    """Run the method ``name`` (one of :data:`METHODS`) on ``demo``.

    Raises:
        SettingsError: an unknown method name.
    """
    if name not in _FUNCTIONS:
        raise SettingsError(f"unknown method {name!r}; expected one of {', '.join(METHODS)}")
    return _FUNCTIONS[name](robot, demo, settings, model=model, network=network)


def mean_objective(robot: Robot, demo, angles, weights: LossWeights | None = None) -> float:
    """Mean over frames of ``L(D, K(q))`` (no latent term) of ``angles (T, n)``."""
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    q = torch.as_tensor(np.asarray(angles), dtype=robot.lower_limits.dtype, device=robot.lower_limits.device)
    with torch.no_grad():
        total, _ = objective(robot, q, targets, weights, cull=True, analytic_fk=True)  # faster forms, same numbers
    return float(total.mean())
