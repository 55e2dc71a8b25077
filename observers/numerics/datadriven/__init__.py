"""Data-driven set-based estimation (Alanwar, Berndt, Johansson, Sandberg, ECC 2022).

:mod:`.learning` computes the set of models ``M_Sigma`` from an offline experiment (the paper's
Lemma 1 and a provably sound construction); :mod:`.updates` holds the measurement updates of
the online phase.  The observers themselves are in :mod:`observers.builtin.datadriven`.
"""

from .learning import (
    SoundModelSet,
    TrainingData,
    check_training,
    hbr_pinv,
    paper_model_set,
    refined_model_set,
    sound_model_set,
)
from .updates import Sensor, implicit_gain, implicit_update, reverse_map, split_sensors

__all__ = [
    "Sensor",
    "SoundModelSet",
    "TrainingData",
    "check_training",
    "hbr_pinv",
    "implicit_gain",
    "implicit_update",
    "paper_model_set",
    "refined_model_set",
    "reverse_map",
    "sound_model_set",
    "split_sensors",
]
