"""What the fork server imports before it forks job workers (:mod:`tcomp_core.workers`).

The numerical core the jobs run (a diagnosis, a signal-model fit, the node's online models),
and numba's compiler contexts: every worker is forked with them in place, so its first job
does not spend a second importing and building them (0.35 s of CPU and more per worker
before this module existed, in each of the node's two workers and again after one dies).
"""

from __future__ import annotations

from . import diagnose, fusion, online  # noqa: F401  (the jobs' modules; online: the node's)
from .compiled import warm_compiler

warm_compiler()
