"""Writing rollout evaluations: Markdown, CSV, JSON and a plot of error against frame."""

from __future__ import annotations

import csv
import io
from pathlib import Path

from loosefit.atomic import atomic_path
from loosefit.data.format import write_json_atomic


def rollout_markdown(result: dict, title: str = "Rollout evaluation") -> str:
    """A table of :func:`loosefit.eval.rollouts.evaluate_rollouts`' result (lengths in cm)."""
    hs = sorted({h for c in result["clips"].values() for h in c["horizons"]}, key=int)
    surface = "hausdorff_cm" in result
    names = ["clip", "frames", "RMSE", *(f"iter-{h}" for h in hs)]
    names += ["Hausdorff", "STED"] if surface else []
    names.append("rollout fps")
    lines = [
        f"# {title}",
        "",
        f"Split `{result['split']}`; rollouts from each clip's first frame; RMSE and "
        "Hausdorff in centimetres; iter-N: RMSE over the first N frames.",
        "",
        "| " + " | ".join(names) + " |",
        "|---|" + "---:|" * (len(names) - 1),
    ]
    rows = list(result["clips"].items()) + [("**all**", result)]
    for name, c in rows:
        cells = [name, str(c["frames"]), f"{c['rmse_cm']:.3f}"]
        cells += [f"{c['horizons'][h]:.3f}" if h in c["horizons"] else "-" for h in hs]
        if surface:
            cells += [f"{c['hausdorff_cm']:.3f}", f"{c['sted']:.4f}"]
        fps = c.get("frames_per_second")
        cells.append(f"{fps:.0f}" if fps else "")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def rollout_csv(result: dict) -> str:
    """One row per clip and frame: ``clip,frame,rmse_cm``."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["clip", "frame", "rmse_cm"])
    for name, c in result["clips"].items():
        for t, e in enumerate(c["rmse_per_frame_cm"]):
            w.writerow([name, t, f"{e:.5f}"])
    return buf.getvalue()


def plot_rollout_error(result: dict, path: Path, title: str = "") -> Path:
    """RMSE (cm) against frame for every clip, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=120)
    for name, c in result["clips"].items():
        ax.plot(c["rmse_per_frame_cm"], lw=1.0, label=name)
    for h in result.get("horizons", {}):
        ax.axvline(int(h), color="0.7", lw=0.8, ls="--")
    ax.set_xlabel("frame of the rollout")
    ax.set_ylabel("RMSE (cm)")
    ax.set_ylim(bottom=0)
    ax.set_title(title or f"rollout error, split {result['split']}")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp)
    plt.close(fig)
    return path


def write_rollout_report(result: dict, out: str | Path, title: str = "Rollout evaluation"):
    """``evaluation.md``, ``evaluation.csv``, ``evaluation.json`` and ``rmse_per_frame.png``.

    The JSON is written last, so a folder with it holds a whole report.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "evaluation.json").unlink(missing_ok=True)
    text = rollout_markdown(result, title)
    if result.get("ensemble"):  # scored against each clip's members too
        from loosefit.eval.ensemble import ensemble_markdown

        text = text.rstrip() + "\n\n" + ensemble_markdown(result["ensemble"]) + "\n"
    (out / "evaluation.md").write_text(text)
    (out / "evaluation.csv").write_text(rollout_csv(result))
    plot_rollout_error(result, out / "rmse_per_frame.png", title)
    write_json_atomic(out / "evaluation.json", result)
    return out


def splice_section(text: str, heading: str, section: str) -> str:
    """A Markdown page with ``section`` (starting with the line ``heading``, a ``## ``
    heading) in place of its section of that heading, up to the next ``## `` heading; a
    page without one gets it before its second ``## `` section (after the first)."""
    lines = text.splitlines()
    heads = [i for i, line in enumerate(lines) if line.startswith("## ")]
    start = next((i for i in heads if lines[i] == heading), None)
    if start is None:
        start = end = heads[1] if len(heads) > 1 else len(lines)
    else:
        end = next((i for i in heads if i > start), len(lines))
    out = lines[:start] + section.rstrip().splitlines() + [""] + lines[end:]
    return "\n".join(out).rstrip() + "\n"


def as_section(text: str, heading: str) -> str:
    """A Markdown page (its first line the ``# `` title) as the section ``heading`` (a
    ``## `` heading) of another page: the title gives way to ``heading`` and every heading
    of the page goes one level down (``## `` to ``### ``; fenced code left as it is)."""
    lines = text.rstrip().splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    out, fenced = [heading], False
    for line in lines:
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and line.startswith("#") and line.lstrip("#").startswith(" "):
            line = "#" + line
        out.append(line)
    return "\n".join(out) + "\n"


def write_section(path: str | Path, heading: str, page: str) -> None:
    """Put ``page`` (a Markdown page with a ``# `` title) in the page at ``path`` as its
    section ``heading`` (:func:`as_section`, :func:`splice_section`), the rest of that page
    kept; a page not there yet is made of the section alone."""
    path = Path(path)
    text = path.read_text(encoding="utf-8") if path.is_file() else ""
    path.write_text(splice_section(text, heading, as_section(page, heading)), encoding="utf-8")
