"""The exception hierarchy of tcomp.

Every error raised on purpose derives from :class:`TcompError` and from the built-in exception a
caller would expect, so ``except ValueError`` keeps working for code that does not know tcomp.
Messages name what is wrong and where: the file, column or topic, the sample index and the value.
"""

from __future__ import annotations

__all__ = [
    "DataError",
    "EstimationError",
    "InvalidReadingsWarning",
    "NoExcitationError",
    "PhysicalRangeError",
    "TcompError",
    "TcompWarning",
    "TruncatedInputWarning",
]


class TcompError(Exception):
    """Base class of every error tcomp raises on purpose."""


class DataError(TcompError, ValueError):
    """The input data are malformed: missing, non-finite, misaligned or unreadable."""


class NoExcitationError(DataError):
    """The data carry no information on the time constants (for example a constant signal)."""


class EstimationError(TcompError, ArithmeticError):
    """An estimator could not produce a physically meaningful result."""


class PhysicalRangeError(EstimationError, ValueError):
    """An estimated discrete pole ``a`` lies outside (0, 1), so no positive time constant fits."""


class TcompWarning(UserWarning):
    """Base class of every warning tcomp issues on purpose (never a RuntimeWarning).

    The ``tcomp`` command prints each as one line ``tcomp VERB: warning: MESSAGE``.
    """


class TruncatedInputWarning(TcompWarning):
    """An input ends early (a bag still being written, or cut off); it was read up to there."""


class InvalidReadingsWarning(TcompWarning):
    """Samples of an input were left out (readings not finite or outside the physical range).

    Also a repeated time, or a gas not written; the message counts them and names the first.
    """
