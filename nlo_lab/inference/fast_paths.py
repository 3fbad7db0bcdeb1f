"""Which evaluation of each computation the optimisers run: the readable one, or a faster one.

Called directly, the decoder (``GraphDecoder``), the objective (``Objective``) and FK
(``Robot.map_points``) run the code as the paper writes it, so a learner's debugger steps
into the equations. Each also has a faster evaluation of the same numbers (tested equal,
values and gradients), taken only when a caller asks for it by an argument:

* the decoder's ``form``: ``"node-major"`` (weights gathered per edge, constant inputs
  folded in) or ``"numpy"`` (that in numpy with a written-out gradient; frozen weights);
* the objective's ``fused`` (the terms in numpy with a written-out gradient) and ``cull``
  (exact capsule distances only for the pairs that may be within their margin);
* FK's ``analytic_gradient`` (the closed-form derivative of the mapped points);
* and for a few frames the whole iteration in numpy (loss and gradient written out, no
  autograd: :mod:`nlo_lab.inference.numpy_descent`); for more frames, or a sequence with the
  smoothness term, the iteration's gradient chained by hand through FK, the terms and the smoothness
  term (``written_gradient``; the node-major decoder's gradient written out too, else its own graph).

:class:`FastPaths` holds one such choice; :meth:`FastPaths.for_frames` makes it from the
batch size, with the measured crossovers below. Nothing is process-wide: the pipeline
(``RetargetConfig(fast=True).build()``, the default) and training pass it explicitly, and
``fast=False`` runs the readable forms everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from nlo_lab.errors import SettingsError
from nlo_lab.model import DECODER_FORMS
from nlo_lab.settings import check_choice

__all__ = ["FastPaths", "fast_paths", "DECODER_NUMPY_MAX_BATCH"]

# Measured crossovers on one CPU thread (YuMi, forward + backward):
# numpy decoder, batch 1 266 vs 473 us (torch node-major), 170: 15.4 vs 2.6 ms (numpy's
# stacked small matmuls do not batch)
DECODER_NUMPY_MAX_BATCH = 8
# The objective's numpy terms (hand terms included, far capsule pairs culled) run on the CPU at
# any batch: against the torch terms with culling, FK + terms, forward + backward, CPU time,
# YuMi (318 capsule pairs) 1 frame 1.1 vs 2.7 ms, 96: 4.4 vs 6.5, 170: 6.7 vs 9.7, 680: 26 vs 42 ms;
# NAO 170: 2.2 vs 3.3 ms, 680: 6.7 vs 8.9 ms.


@dataclass(frozen=True)
class FastPaths:
    """One choice of evaluation per computation; the defaults are the readable forms.

    Attributes:
        decoder: the decoder's ``form`` (``"paper"``, ``"node-major"``, ``"numpy"``).
        fused_objective: the objective's terms in numpy (``Objective(fused=True)``).
        cull_far_pairs: exact capsule distances only where a pair may be near (``Objective(cull=True)``).
        analytic_fk: FK's closed-form gradient (``Objective(analytic_fk=True)``).
        numpy_iteration: latent optimisation evaluates its loss and gradient in numpy
            (:class:`~nlo_lab.inference.numpy_descent.NumpyLatentLoss`), where the decoder and
            the objective have numpy forms and no sequence term couples the frames.
        hand_chains: the hand stage maps only the points its hand joints move, by FK from the wrists
            down (:class:`~nlo_lab.inference.hand_stage.HandChains`; the arms are fixed there).
        written_gradient: latent optimisation chains the gradient by hand where ``numpy_iteration`` does not
            apply (:class:`~nlo_lab.inference.numpy_descent.WrittenGradientLoss`; needs ``fused_objective``; with the
            ``"node-major"`` decoder its gradient too, :class:`~nlo_lab.model.written_gradient.WrittenDecoder`),
            and so does the hand stage (:class:`~nlo_lab.inference.hand_stage.HandStageLoss`; with ``hand_chains``).
    """

    decoder: str = "paper"
    fused_objective: bool = False
    cull_far_pairs: bool = False
    analytic_fk: bool = False
    numpy_iteration: bool = False
    hand_chains: bool = False
    written_gradient: bool = False

    def __post_init__(self) -> None:
        check_choice("decoder form", self.decoder, DECODER_FORMS)
        for name in ("fused_objective", "cull_far_pairs", "analytic_fk", "numpy_iteration", "hand_chains", "written_gradient"):
            if not isinstance(getattr(self, name), bool):
                raise SettingsError(f"FastPaths {name} must be True or False, got {getattr(self, name)!r}")

    @classmethod
    def readable(cls) -> FastPaths:
        """Every computation in its readable form (the paper's decoder, the term functions, autograd through FK)."""
        return cls()

    @classmethod
    def for_frames(cls, frames: int, device: torch.device | str = "cpu") -> FastPaths:
        """The fastest forms for a batch of ``frames`` on ``device`` (the crossovers above)."""
        cpu = torch.device(device).type == "cpu"
        return cls(
            decoder="numpy" if cpu and frames <= DECODER_NUMPY_MAX_BATCH else "node-major",
            fused_objective=cpu,
            cull_far_pairs=True,
            analytic_fk=True,
            numpy_iteration=cpu and frames <= DECODER_NUMPY_MAX_BATCH,
            hand_chains=True,
            written_gradient=cpu,
        )

    def objective_options(self) -> dict[str, bool]:
        """``Objective``'s keyword arguments for this choice."""
        return {"fused": self.fused_objective, "cull": self.cull_far_pairs, "analytic_fk": self.analytic_fk}


def fast_paths(fast: bool | FastPaths, frames: int, device: torch.device | str = "cpu") -> FastPaths:
    """``fast`` as a :class:`FastPaths`: True = :meth:`FastPaths.for_frames`, False = readable, or itself."""
    if isinstance(fast, FastPaths):
        return fast
    if not isinstance(fast, bool):
        raise SettingsError(f"fast must be True, False or a FastPaths, got {fast!r}")
    return FastPaths.for_frames(frames, device) if fast else FastPaths.readable()
