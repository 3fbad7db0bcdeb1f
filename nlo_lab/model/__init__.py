"""The networks of neural latent optimisation: graph layer, encoder, decoder, checkpoints.

- :mod:`~nlo_lab.model.layers`: the paper's :class:`GraphLayer` and the limit remap.
- :mod:`~nlo_lab.model.encoder`: human features -> latent ``z`` (:class:`GraphEncoder`, :class:`MLPEncoder`).
- :mod:`~nlo_lab.model.decoder`: ``z`` -> joint angles inside the limits (:class:`GraphDecoder`, :class:`MLPDecoder`).
- :mod:`~nlo_lab.model.numpy_backend`: the frozen graph decoder in numpy, a faster evaluation
  of the same map for small batches (``decoder(z, form="numpy")``).
- :mod:`~nlo_lab.model.written_gradient`: the frozen graph decoder in torch without an autograd graph, its
  gradient to ``z`` written out (``GraphDecoder.written()``, a recording's latent optimisation).
- :mod:`~nlo_lab.model.retarget_model`: :class:`RetargetModel` (encoder + decoder), :func:`build_model`.
- :mod:`~nlo_lab.model.encoder_input`: :class:`EncoderInput`, what the encoder reads of a demonstration.
- :mod:`~nlo_lab.model.checkpoint`: save, load, and the shipped checkpoints (:func:`load_pretrained`).
"""

from nlo_lab.model.checkpoint import CHECKPOINT_FORMAT_VERSION, checkpoint_path, load_checkpoint, load_pretrained, save_checkpoint
from nlo_lab.model.decoder import DECODER_FORMS, GraphDecoder, MLPDecoder
from nlo_lab.model.encoder import GraphEncoder, MLPEncoder
from nlo_lab.model.encoder_input import EncoderInput, encoder_input
from nlo_lab.model.layers import (
    ACTIVATIONS,
    DEFAULT_ACTIVATION,
    LEAKY_SLOPE,
    GraphLayer,
    activation_function,
    remap_to_limits,
    rest_preactivation,
)
from nlo_lab.model.retarget_model import MODEL_KINDS, RetargetModel, build_model

__all__ = [
    # layers, encoder, decoder, the model
    "GraphLayer", "remap_to_limits", "rest_preactivation", "LEAKY_SLOPE",
    "ACTIVATIONS", "DEFAULT_ACTIVATION", "activation_function",
    "GraphEncoder", "MLPEncoder", "GraphDecoder", "MLPDecoder", "DECODER_FORMS",
    "RetargetModel", "build_model", "MODEL_KINDS",
    # the encoder's input
    "EncoderInput", "encoder_input",
    # checkpoints
    "CHECKPOINT_FORMAT_VERSION", "save_checkpoint", "load_checkpoint", "checkpoint_path", "load_pretrained",
]  # fmt: skip
