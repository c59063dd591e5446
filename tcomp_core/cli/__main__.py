"""``python -m tcomp_core.cli``: the ``tcomp`` command."""

from __future__ import annotations

import sys

from . import main

sys.exit(main())
