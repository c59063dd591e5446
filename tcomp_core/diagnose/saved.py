"""The effects a saved diagnosis found: ``tcomp diagnose --json`` read back.

A test cell diagnoses one recording of a probe and compensates the others with the physics it
found (``tcomp reconstruct --effects diagnosis.json``, ``tcomp process``, ``tcomp campaign``),
each fitting those effects on its own record, as a list given by name would be, without
diagnosing again.

A diagnosis that ended ``unexplained`` found no physics, and is refused: its final model is
first order, which the diagnosis itself found wanting. On fresh draws of an independent
simulator such a file put another recording of the same probe 195 % and 24.7 % off where that
recording's own diagnosis (``--effects auto``) got 2.69 % and 7.55 %.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..choices import names_a_saved_diagnosis, parse_effect_list
from ..errors import DataError

__all__ = ["effects_of_diagnosis", "read_diagnosis_effects", "saved_diagnosis_effects"]

#: The verdict of a diagnosis whose final model leaves the record well above its noise with
#: no effect found (:func:`~tcomp_core.diagnose.unexplained.is_unexplained`).
UNEXPLAINED = "unexplained"


def effects_of_diagnosis(document: Mapping[str, Any]) -> tuple[str, ...]:
    """The effects of a diagnosis document's final model, in the order it added them.

    Parameters
    ----------
    document : mapping
        What :func:`~tcomp_core.diagnose.diagnosis_to_dict` returns (the final model's
        ``final.effects``), or, for a record diagnosed in windows,
        :func:`~tcomp_core.diagnose.windowed.windowed_to_dict` (the effects of the first window
        giving the whole record's ``verdict``).

    Returns
    -------
    tuple of str
        Effect names; empty when the first-order model was the final one.

    Raises
    ------
    ValueError
        If the document holds neither, names an unknown effect, or its verdict is
        ``unexplained``: no effect it tried explained its record, so its final model is no
        physics found (first order at best) and compensating another record with it would
        publish a gas the diagnosis itself did not trust.
    """
    if document.get("verdict") == UNEXPLAINED:
        signature = document.get("unexplained")
        said = f" (its residual: {signature})" if isinstance(signature, str) and signature else ""
        raise ValueError(
            f"that diagnosis ended {UNEXPLAINED!r}: no effect it tried explained its record"
            f"{said}, so it found no physics to compensate with; diagnose each record instead "
            "(--effects auto) or name the effects"
        )
    final = document.get("final")
    if isinstance(final, Mapping) and "effects" in final:
        return _names(final["effects"], "final.effects")
    verdict, windows = document.get("verdict"), document.get("windows")
    if isinstance(verdict, str) and isinstance(windows, list):
        for number, row in enumerate(windows):
            if isinstance(row, Mapping) and row.get("verdict") == verdict:
                return _names(row.get("effects"), f"windows[{number}].effects")
        raise ValueError(f"no window gives the whole record's verdict {verdict!r}")
    raise ValueError(
        "no diagnosis in it: 'tcomp diagnose --json' writes the final model's effects under "
        "final.effects (or, in windows, a verdict and the windows giving it)"
    )


def _names(value: object, where: str) -> tuple[str, ...]:
    """Effect names from a document's list at ``where``, checked as ``--effects`` checks them."""
    if not (isinstance(value, list) and all(isinstance(name, str) for name in value)):
        raise ValueError(f"{where} is {value!r}, not a list of effect names")
    return parse_effect_list(value) or ()


def read_diagnosis_effects(path: str | Path) -> tuple[str, ...]:
    """:func:`effects_of_diagnosis` of the JSON file ``path``.

    Raises
    ------
    DataError
        Naming the file and what is wrong with it (missing, unreadable, not JSON, no
        diagnosis, an unknown effect).
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"{path}: no such diagnosis file") from None
    except OSError as error:
        raise DataError(f"{path}: cannot read the diagnosis ({error.strerror})") from error
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise DataError(f"{path}: not a diagnosis written as JSON ({error})") from error
    if not isinstance(document, Mapping):
        raise DataError(f"{path}: not a diagnosis (a JSON object is expected)")
    try:
        return effects_of_diagnosis(document)
    except ValueError as error:
        raise DataError(f"{path}: {error}") from error


def saved_diagnosis_effects(effects: str) -> str:
    """An ``effects`` value with a saved diagnosis (``*.json``) replaced by its effects.

    Returns the final model's effects comma-separated (``"none"`` for first order), as
    ``--effects`` and the node's ``effects`` take a list; any other value as given.

    Raises
    ------
    DataError
        As :func:`read_diagnosis_effects`.
    """
    if not names_a_saved_diagnosis(effects):
        return effects
    return ",".join(read_diagnosis_effects(effects.strip())) or "none"
