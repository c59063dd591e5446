"""``tcomp campaign``: every recording of every probe, processed and diagnosed on Dask.

:func:`run_campaign` finds the recordings (:mod:`.inputs`), runs each as one task on a Dask
cluster (:mod:`.cluster`; :func:`~.task.run_recording`, the engine of ``tcomp process`` and the
windowed diagnosis of ``tcomp diagnose``), keeps every result by content key (:mod:`.ledger`),
and writes the table (:mod:`.table`) and the HTML report (:mod:`.report`).
"""

from .cluster import ClusterSpec
from .inputs import ProbeRule, Recording, find_recordings
from .run import CampaignResult, run_campaign
from .task import CampaignOptions, run_recording

__all__ = [
    "CampaignOptions",
    "CampaignResult",
    "ClusterSpec",
    "ProbeRule",
    "Recording",
    "find_recordings",
    "run_campaign",
    "run_recording",
]
