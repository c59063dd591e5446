"""Where the sample bags shipped with tcomp live: the checkout's ``bags/`` or the installed share.

In a source checkout the bags sit in ``bags/`` beside the packages. A colcon (ament_python) install
puts them in ``<prefix>/share/tcomp_ros/bags`` and the packages in
``<prefix>/lib/pythonX.Y/site-packages``, so both are found from this file's location whatever the
working directory.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["bundled_bag", "bundled_bags_directory"]

_PACKAGE = "tcomp_ros"


def _candidates() -> list[Path]:
    here = Path(__file__).resolve().parent  # .../tcomp_core
    candidates = [here.parent / "bags"]  # source checkout (or an editable install)
    # <prefix>/lib/pythonX.Y/site-packages/tcomp_core -> <prefix>/share/tcomp_ros/bags
    if len(here.parents) >= 4:
        candidates.append(here.parents[3] / "share" / _PACKAGE / "bags")
    return candidates


def bundled_bags_directory() -> Path:
    """The directory holding the bundled bags.

    Returns
    -------
    Path
        The checkout's ``bags/`` or the installed ``share/tcomp_ros/bags``, the first that exists
        (the checkout's when neither does, so an error names a path a user recognises).
    """
    candidates = _candidates()
    return next((path for path in candidates if path.is_dir()), candidates[0])


def bundled_bag(name: str) -> Path:
    """Path of the bundled bag ``name`` (a directory such as ``rig_sine_5khz``).

    A ``bags/<name>`` under the working directory wins (running from the checkout, or a user's
    own ``bags/``); otherwise the bundled copy, wherever tcomp is installed.
    """
    local = Path("bags") / name
    return local if local.exists() else bundled_bags_directory() / name
