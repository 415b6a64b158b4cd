"""Writing a suite's matplotlib figure to a PNG, the same way for every suite."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def save_figure(fig: Any, path: Path) -> Path:
    """Lay `fig` out, write it to `path` (folders created) at 110 dpi and close it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
