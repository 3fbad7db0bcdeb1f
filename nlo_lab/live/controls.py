"""Sliders that change a running live stream: the loss weights, the iteration budget and the landmark filter.

:class:`LiveControls` is a plain object that tests drive headlessly: set ``controls.sliders[name].value``
and the :class:`~nlo_lab.live.LiveRetargeter` takes the new value from its next frame on (observers fire
as in the browser). The weights are log sliders (0 is the left end: the term off), like notebook 03's.
"""

from __future__ import annotations

from nlo_lab.live.retargeter import LiveRetargeter
from nlo_lab.objective import TERMS

__all__ = ["LiveControls", "WEIGHT_SLIDERS"]

WEIGHT_SLIDERS = tuple(t for t in TERMS)  # ee, ori, elbow, finger, collision, tip, thumb, pinch
_OFF = 0.01  # a log slider's left end: the term off


class LiveControls:
    """One slider per loss weight, the iterations per frame and the One-Euro filter's ``min_cutoff`` and ``beta``.

    Args:
        retargeter: the :class:`LiveRetargeter` to steer (a :class:`~nlo_lab.live.CameraView`'s ``retargeter``).

    Attributes:
        sliders: ``{name: slider}`` (weights by term name, ``"iterations"``, ``"min_cutoff"``, ``"beta"``).
        widget: the sliders in a box (what is shown).
    """

    def __init__(self, retargeter: LiveRetargeter):
        import ipywidgets as W

        self.retargeter = retargeter
        style, layout = {"description_width": "90px"}, W.Layout(width="360px")
        weights = retargeter.weights
        self.sliders = {
            name: W.FloatLogSlider(value=max(float(getattr(weights, name)), _OFF), base=10, min=-2, max=4, step=0.1,
                                   description=name, style=style, layout=layout, continuous_update=False)
            for name in WEIGHT_SLIDERS
        }
        self.sliders["iterations"] = W.IntSlider(value=retargeter.iterations, min=1, max=100, description="iterations",
                                                 style=style, layout=layout, continuous_update=False)
        f = retargeter.filter
        self.sliders["min_cutoff"] = W.FloatLogSlider(value=f.min_cutoff, base=10, min=-1, max=1.5, step=0.05,
                                                      description="min_cutoff [Hz]", style=style, layout=layout, continuous_update=False)
        self.sliders["beta"] = W.FloatSlider(value=f.beta, min=0.0, max=10.0, step=0.1, description="beta [1/m]",
                                             style=style, layout=layout, continuous_update=False)
        for name, slider in self.sliders.items():
            slider.observe(lambda change, name=name: self._changed(name, change["new"]), names="value")
        self.widget = W.HBox([W.VBox([W.HTML("<b>loss weights</b>"), *(self.sliders[n] for n in WEIGHT_SLIDERS)]),
                              W.VBox([W.HTML("<b>optimisation and filter</b>"), self.sliders["iterations"],
                                      self.sliders["min_cutoff"], self.sliders["beta"]])],
                             layout=W.Layout(flex_flow="row wrap"))

    def _changed(self, name: str, value) -> None:
        live = self.retargeter
        if name == "iterations":
            live.set_iterations(int(value))
        elif name in ("min_cutoff", "beta"):
            live.set_filter(**{name: float(value)})
        else:
            live.set_weights(**{name: 0.0 if value <= _OFF else float(value)})

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)
