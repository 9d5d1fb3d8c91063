"""Where the shared data folder is (the draft corpus, public documents, catalogue sources): $DRIVEMAP_SHARED,
else ``shared/`` beside the repository (CI clones the repository beside a copy of it)."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def shared_dir() -> Path:
    return Path(os.environ.get("DRIVEMAP_SHARED") or ROOT.parent / "shared")
