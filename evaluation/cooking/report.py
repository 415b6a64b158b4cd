"""The cooking experiment's files (paper Fig. 9) and its section in the paper report.

`write_cooking_report` is how `coexist eval --suite cooking` (`evaluation.cooking.command`)
writes the results of the paired episodes of `evaluation.cooking.suite`: these files in `out`
(`reports/cooking` by default; the hand-written `README.md` there is never touched):

| file               | content                                                            |
|--------------------|--------------------------------------------------------------------|
| `results.md`       | the results table, the paired tests, the networks, the command     |
| `results.json`     | settings, summary per method and cook, and every episode's numbers |
| `fig9_cooking.png` | dish completion ratios ± standard error (paper Fig. 9)             |
| `aail_episode.gif` | the first AAIL-B episode (the default blend)                       |

The paper report (`reports/paper/REPORT.md`) carries the result as its section
`COOKING_HEADING`, rendered from `results.json` by `cooking_section`: `evaluation.paper.report`
includes it whenever the paper suite is re-run, and a cooking run rewrites that section of an
existing paper report in place (`update_paper_report`), so neither run loses the other's result.
By convention the paper report lives in `paper/` beside the cooking folder.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.command_line import portable_command, portable_path, variables_note
from evaluation.cooking.suite import (
    RECIPES,
    CookingResults,
    evaluate_cooking,
    plot_cooking,
    save_cooking_gif,
)

COOKING_HEADING = "## Cooking kitchen"
RESULTS_JSON = "results.json"
FIGURE = "fig9_cooking.png"
GIF = "aail_episode.gif"
PAPER_REPORT = Path("paper") / "REPORT.md"  # relative to the cooking folder's parent


def results_json(results: CookingResults, **settings: Any) -> dict[str, Any]:
    """Everything `results_from_json` needs, plus a summary a reader can take in at a glance."""
    summary = {
        f"{method}/{agent}": {
            "completion": results.completion(method, a).mean,
            "completion_se": results.completion(method, a).se,
            "return": results.mean_return(method, a).mean,
            "return_se": results.mean_return(method, a).se,
        }
        for method in results.methods
        for a, agent in enumerate(("left", "right"))
    }
    return {
        **settings,
        "episodes": results.episodes,
        "seed": results.seed,
        "max_steps": results.max_steps,
        "temperature": results.temperature,
        "methods": list(results.methods),
        "right_cook": results.right_cook,
        "models": results.models,
        "summary": summary,
        "served_MEN": results.served_MEN.astype(int).tolist(),
        "steps_MEN": results.steps_MEN.tolist(),
        "returns_MEN": np.round(results.returns_MEN, 4).tolist(),
    }


def results_from_json(data: dict[str, Any]) -> CookingResults:
    """The results of a `results.json` (without the recorded episode)."""
    try:
        return CookingResults(
            methods=tuple(data["methods"]),
            seed=int(data["seed"]),
            max_steps=int(data["max_steps"]),
            right_cook=str(data["right_cook"]),
            served_MEN=np.asarray(data["served_MEN"], dtype=bool),
            steps_MEN=np.asarray(data["steps_MEN"], dtype=np.int64),
            returns_MEN=np.asarray(data["returns_MEN"], dtype=np.float64),
            models={k: list(v) for k, v in data.get("models", {}).items()},
            temperature=data.get("temperature"),
        )
    except KeyError as err:
        raise ValueError(f"cooking results.json: missing field {err.args[0]!r}") from None


def write_cooking_files(
    results: CookingResults, out: Path, *, command: str, backend: str, wall_s: float
) -> Path:
    """results.md, results.json, the Fig. 9 plot and the GIF (when an episode was recorded)."""
    out.mkdir(parents=True, exist_ok=True)
    plot_cooking(results, out / FIGURE)
    if results.trajectory:
        save_cooking_gif(results, out / GIF)
    note = variables_note(command)
    footer = f"\n\nCommand: `{command}` ({backend}, {wall_s:.0f} s).{' ' + note if note else ''}\n"
    (out / "results.md").write_text(results.to_markdown() + footer, encoding="utf-8")
    payload = results_json(results, command=command, backend=backend, wall_s=round(wall_s, 1))
    path = out / RESULTS_JSON
    path.write_text(json.dumps(payload, indent=1), encoding="utf-8")
    return path


def cooking_section(cooking_dir: Path, report_dir: Path) -> str:
    """The paper report's cooking section (heading included), links relative to `report_dir`."""
    rel = Path(os.path.relpath(cooking_dir, report_dir)).as_posix()
    title = f"{COOKING_HEADING} (paper §4.3-4.4, Fig. 9)"
    file = cooking_dir / RESULTS_JSON
    if not file.exists():
        return (
            f"{title}\n\nNot run yet: `coexist eval --suite cooking --out "
            f"{portable_path(cooking_dir)}` "
            f"writes the results to `{rel}/` and this section."
        )
    data = json.loads(file.read_text(encoding="utf-8"))
    results = results_from_json(data)
    lines = [
        title,
        "",
        f"The left cook ({RECIPES[0]}) is controlled by AAIL-B, AAIL or SL; the right cook "
        f"({RECIPES[1]}) needs the carrot only the left cook can reach. Generated from "
        f"[`{rel}/{RESULTS_JSON}`]({rel}/{RESULTS_JSON}) (command: `{data.get('command', '?')}`); "
        f"training, gates and discussion in [`{rel}/README.md`]({rel}/README.md).",
        "",
        results.to_markdown(),
    ]
    if (cooking_dir / FIGURE).exists():
        lines += ["", f"![Fig. 9]({rel}/{FIGURE})"]
    return "\n".join(lines)


def update_paper_report(report: Path, section: str) -> bool:
    """Replace the cooking section of an existing `report` (or append it, where
    `evaluation.paper.report` puts it: last); False when there is no report to update."""
    if not report.exists():
        return False
    lines = report.read_text(encoding="utf-8").split("\n")
    starts = [i for i, line in enumerate(lines) if line.startswith(COOKING_HEADING)]
    if starts:
        start = starts[0]
        ends = [i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")]
        end = ends[0] if ends else len(lines)
    else:
        while lines and not lines[-1].strip():
            lines.pop()
        lines.append("")
        start = end = len(lines)
    new = [*section.split("\n"), ""]
    report.write_text("\n".join(lines[:start] + new + lines[end:]), encoding="utf-8")
    return True


def write_cooking_report(
    results: CookingResults, out: Path, *, command: str, backend: str, wall_s: float
) -> Path | None:
    """The files of `out`, and the paper report's section refreshed; returns the paper report
    it updated (None when there is none beside `out`)."""
    write_cooking_files(results, out, command=command, backend=backend, wall_s=wall_s)
    report = out.resolve().parent / PAPER_REPORT
    section = cooking_section(out.resolve(), report.parent)
    return report if update_paper_report(report, section) else None


def main(argv: list[str]) -> None:
    """`python -m evaluation.cooking STORE_URL OUT_DIR [EPISODES [TEMPERATURE]]` (the CLI's
    `coexist eval --suite cooking` is the usual way; this one also takes a temperature)."""
    import torch

    from evaluation.backend import EngineBackend
    from model_store.defaults import open_store
    from services.engine import InferenceEngine

    torch.set_num_threads(1)
    store_url, out = argv[0], Path(argv[1])
    episodes = int(argv[2]) if len(argv) > 2 else 100
    temperature = float(argv[3]) if len(argv) > 3 else None
    with open_store(store_url) as store:
        backend = EngineBackend(InferenceEngine(store))
        start = time.perf_counter()
        results = evaluate_cooking(backend, episodes=episodes, temperature=temperature)
        command = portable_command(["python", "-m", "evaluation.cooking", *argv])
        write_cooking_files(
            results,
            out,
            command=command,
            backend=backend.description,
            wall_s=time.perf_counter() - start,
        )
    print(results.to_markdown())
