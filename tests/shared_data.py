"""Where the real recordings and models are, for every test that reads them: the folder named by the
environment variable LTC_SHARED, else ``../shared`` beside the repository, else /work/shared (a git
worktree of the repository sits elsewhere than beside it)."""

from __future__ import annotations

import os
from pathlib import Path


def shared_dir() -> Path:
    candidates = [Path(__file__).resolve().parents[2] / "shared"]
    if os.environ.get("LTC_SHARED"):
        candidates.insert(0, Path(os.environ["LTC_SHARED"]))
    candidates.append(Path("/work/shared"))
    return next((p for p in candidates if (p / "data").is_dir()), candidates[0])


SHARED = shared_dir()
