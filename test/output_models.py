"""Output models with given parameters, for the compensation tests."""

from __future__ import annotations

import numpy as np

from tcomp_core.compensation import OutputModel, Piece
from tcomp_core.effects import make_context

#: Sample interval of the test records, s (500 Hz).
DT = 0.002


def model_with(
    effects: tuple[str, ...],
    params: dict,
    n: int = 5000,
    level_c: float = 600.0,
    **fields,
) -> OutputModel:
    """An output model with given parameters over an n-sample record at 500 Hz.

    ``fields`` sets other fields of the model (``error_pct``, ``at_bound``, ...).
    """
    time = np.arange(n) * DT
    level = np.full(n, level_c)
    context = make_context(time, level, level, DT)
    return OutputModel(
        effects=effects,
        params={"tau1": 0.0238, "tau2": 0.1168, **params},
        context=context,
        # As the rules have them: a calibration keeps the first-order level.
        pieces=tuple(
            Piece(e, "dynamics" if e == "calibration" else "compensated", "test") for e in effects
        ),
        **fields,
    )


STREAM_MODELS = {
    "delay": (("delay",), {"delay_s": 0.0131}),
    "conduction": (("conduction",), {"tau_leg": 0.3, "tau_p": 1.2, "mode1": 0.0, "mode2": 0.0}),
    "radiation": (("radiation",), {"rho1": 0.05, "rho2": 0.12, "wall_c": 400.0}),
    "interference": (
        ("interference",),
        {
            "interference_hz": 50.0,
            "interference_channel": 2.0,
            **{f"interference_{c}{h}": 0.3 / h for c in "ab" for h in (1, 3, 5)},
        },
    ),
    "calibration+delay": (
        ("calibration", "delay"),
        {"gain": 1.02, "offset_c": -3.0, "delay_s": -0.004},
    ),
}
