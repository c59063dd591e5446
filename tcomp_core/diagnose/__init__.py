"""Compare the model with measurements, find where it fails and which effect is missing."""

from __future__ import annotations

from .pipeline import diagnose, fit_effects
from .result import Diagnosis, ModelFit, Suspect, diagnosis_to_dict

__all__ = ["Diagnosis", "ModelFit", "Suspect", "diagnose", "diagnosis_to_dict", "fit_effects"]
