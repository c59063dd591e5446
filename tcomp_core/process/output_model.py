"""``tcomp process --effects``: the output model fitted on the record's first pairs.

The pairs are matched as the engine matches them (:class:`~tcomp_core.online.PairMatcher`, the
same slop and queue), the longest gap-free stretch of the first ``diagnose_samples`` is fitted
(:func:`tcomp_core.compensation.fit_output_model`: the diagnosis for ``auto``, else the effects
given) and the whole record is then streamed with that model from its first pair on, exactly as
the compensator node publishes once it is handed the model.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..compensation import OutputModel, fit_output_model
from ..errors import DataError
from ..io import Record, TemperatureBatch, open_stream
from ..online import PairMatcher, Pairs
from ..online.extended import longest_stretch

__all__ = ["FittedOutput", "fit_stream_output_model"]

#: The two inputs' samples reach the matcher in stamp slices of at most this fraction of its
#: queue each.
_SLICE_OF_QUEUE = 0.25


@dataclass(frozen=True)
class FittedOutput:
    """An output model and the record it was fitted on.

    Attributes
    ----------
    model : OutputModel
    origin_ns : int
        Stamp of the fitted record's sample 0, ns.
    record : (ndarray, ndarray, ndarray)
        Stamps (ns), tc1, tc2 of the fitted pairs.
    seconds : float
        Wall time of the fit.
    """

    model: OutputModel
    origin_ns: int
    record: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]
    seconds: float

    def note(self, effects: str) -> str:
        """What the diagnostics say of the model (``output_model_note``)."""
        how = "diagnosis" if effects.strip() == "auto" else f"effects {effects.strip()}"
        return f"fitted on the first {self.record[0].size} pairs ({how})"


def fit_stream_output_model(
    source: Path,
    effects: tuple[str, ...] | None,
    *,
    topics: tuple[str, str, str | None],
    columns: tuple[str, str, str | None],
    samples: int,
    slop_ns: int,
    queue_size: int,
    valid_range: tuple[float, float],
    gap_factor: float,
) -> FittedOutput:
    """Fit the output model on the longest gap-free stretch of the first ``samples`` pairs.

    Raises
    ------
    DataError
        When the record has no pairs, or too few for a fit.
    EstimationError
        When the fit fails.
    """
    started = time.perf_counter()
    matcher = PairMatcher(slop_ns=slop_ns, queue_size=queue_size, valid_range=valid_range)
    parts: list[Pairs] = []
    matched = 0
    blocks = iter(open_stream(source, topics=topics, columns=columns))
    # Leaving the reading early closes it at once (its read-ahead thread and files).
    with closing(blocks):  # type: ignore[type-var]  # a generator has close()
        for block in blocks:
            for index, stamps, values in _interleaved(block.series, queue_size):
                pairs = matcher.add_batch(index, stamps, values)
                if len(pairs):
                    parts.append(pairs)
                    matched += len(pairs)
            if matched >= samples:
                break
    if not parts:
        invalid = matcher.counters.as_dict()
        why = ", ".join(
            f"{invalid[f'invalid_{name}']} {name}"
            for name in ("tc1", "tc2")
            if invalid[f"invalid_{name}"]
        )
        low, high = valid_range
        raise DataError(
            f"{source}: no tc1/tc2 pairs to fit the output model on"
            + (f" ({why} readings not finite or outside {low:g}..{high:g} degC)" if why else "")
        )
    pairs = Pairs.concatenate(parts)
    stamps, tc1, tc2 = longest_stretch(
        [pairs.stamps_ns[:samples], pairs.tc1[:samples], pairs.tc2[:samples]], gap_factor
    )
    if stamps.size < 2:
        raise DataError(f"{source}: too few gap-free pairs ({stamps.size}) to fit a model on")
    record = Record(
        time=(stamps - stamps[0]) * 1e-9,
        tc1=tc1,
        tc2=tc2,
        ref=None,
        source=_stretch_name(source, stamps.size, min(samples, len(pairs))),
        dt=float(np.median(np.diff(stamps))) * 1e-9,
    )
    model = fit_output_model(record, effects)
    return FittedOutput(model, int(stamps[0]), (stamps, tc1, tc2), time.perf_counter() - started)


def _stretch_name(source: Path, stretch: int, first: int) -> str:
    """How the fitted record is named in messages: which pairs of ``source`` it holds."""
    if stretch == first:
        return f"{source} (first {first} pairs)"
    return (
        f"{source} (the longest stretch without a gap in its first {first} pairs: {stretch} "
        "pairs; dropped readings and gaps in the stamps cut it)"
    )


def _interleaved(
    series: Mapping[str, TemperatureBatch], queue_size: int
) -> Iterator[tuple[int, NDArray[np.int64], NDArray[np.float64]]]:
    """A block's tc1 and tc2 samples as (input index, stamps, values), interleaved by stamp.

    A block holds each input's samples whole (a CSV block: 100 000 rows); handed over one
    input after the other, the first would overflow the matcher's queue and all but its newest
    ``queue_size`` samples would be dropped (``--diagnose-samples`` fitted 2 000 pairs whatever
    it said). Slices up to the same stamp, a fraction of the queue each, keep them paired.
    """
    batches = [series.get(role) for role in ("tc1", "tc2")]
    present = [batch for batch in batches if batch is not None and len(batch)]
    if not present:
        return
    step = max(1, int(_SLICE_OF_QUEUE * queue_size))
    leader = max(present, key=len).stamps_ns
    bounds = [*leader[step::step].tolist(), None]
    starts = [0, 0]
    for bound in bounds:
        for index, batch in enumerate(batches):
            if batch is None or not len(batch):
                continue
            stop = len(batch) if bound is None else int(np.searchsorted(batch.stamps_ns, bound))
            if stop > starts[index]:
                part = slice(starts[index], stop)
                yield index, batch.stamps_ns[part], batch.temperature[part]
                starts[index] = stop
