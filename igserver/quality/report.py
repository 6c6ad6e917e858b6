"""The common shape of a quality study's results, and the one report ``igserver quality`` writes.

A study module ``igserver/quality/<name>.py`` has ``run(argv)`` (its own CLI, its own detailed
markdown) and, to take part in the combined report, ``study(quick: bool) -> Study``: points of
error against milliseconds, each tagged with the knob it varies (one curve per knob) and, where it
is one, the preset it is. ``write_report`` turns the studies into ``report.md`` (a table per
pipeline) and one PNG per pipeline (error against ms, a curve per knob, presets marked).
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path


@dataclass
class Point:
    knob: str  # the knob this point's curve varies ("steps", "scale", ...; "preset" for the presets)
    setting: str  # the point's settings, human readable ("steps=48 octaves=3 ...")
    error: float  # in the study's metric (lower is better)
    ms: float  # run time the point costs (the study says which: a pass, a frame, amortised or not)
    preset: str | None = None  # "low" | "medium" | "high" when this point is that preset
    extra: dict = field(default_factory=dict)  # more columns (p99 ms, a second metric, ...)


@dataclass
class Study:
    pipeline: str
    metric: str  # e.g. "RMSE, 8-bit sRGB levels over covered pixels"
    time: str  # e.g. "ms, volumes pass per frame (mean, time running)"
    points: list[Point]
    notes: list[str] = field(default_factory=list)
    device: str = ""

    def to_dict(self) -> dict:
        return asdict(self)


def _fmt(value) -> str:
    if isinstance(value, float):
        return "–" if not math.isfinite(value) else (f"{value:.3g}" if abs(value) < 100 else f"{value:.0f}")
    return str(value)


def study_markdown(study: Study, plot_name: str | None) -> list[str]:
    extra_keys = sorted({k for p in study.points for k in p.extra})
    lines = [f"## {study.pipeline}", ""]
    if study.device:
        lines.append(f"Device: {study.device}.")
    lines += [f"Error: {study.metric}. Time: {study.time}.", ""]
    lines += [f"- {note}" for note in study.notes]
    if study.notes:
        lines.append("")
    if plot_name:
        lines += [f"![{study.pipeline}: error against ms]({plot_name})", ""]
    head = ["knob", "setting", "error", "ms", *extra_keys, "preset"]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in study.points:
        cells = [p.knob, p.setting, _fmt(p.error), _fmt(p.ms), *(_fmt(p.extra.get(k, "")) for k in extra_keys),
                 f"**{p.preset}**" if p.preset else ""]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    return lines


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend. matplotlib is the optional extra
    ``igserver[quality]``: the server never needs it, only the report's plots do."""
    try:
        import matplotlib
    except ImportError as exc:
        raise ModuleNotFoundError("the quality report's plots need matplotlib, which is not installed: "
                                  "install igserver[quality] (pip install 'igserver[quality]')",
                                  name="matplotlib") from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_study(study: Study, path: Path) -> None:
    """Error against ms, one curve per knob (points sorted by ms), presets marked and labelled."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=100)
    knobs = [k for k in dict.fromkeys(p.knob for p in study.points) if k != "preset"]
    for knob in knobs:
        pts = sorted((p for p in study.points if p.knob == knob), key=lambda p: p.ms)
        ax.plot([p.ms for p in pts], [p.error for p in pts], marker="o", markersize=3, linewidth=1, label=knob)
    for p in study.points:
        if p.preset:
            ax.plot([p.ms], [p.error], marker="*", markersize=13, color="black", linestyle="none")
            ax.annotate(p.preset, (p.ms, p.error), textcoords="offset points", xytext=(6, 6), fontsize=9)
    positive = [p.ms for p in study.points if p.ms > 0]
    if positive and max(positive) / min(positive) > 20:
        ax.set_xscale("log")
    ax.set_xlabel(study.time)
    ax.set_ylabel(study.metric)
    ax.set_title(f"{study.pipeline}: error against run time (★ presets)")
    ax.grid(True, alpha=0.3)
    if knobs:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def write_report(studies: list[Study], out_dir: Path, failures: dict[str, str] | None = None,
                 header: list[str] | None = None) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = ["# Quality: error against run time, all pipelines", ""]
    lines += header or []
    lines += ["Presets (`quality.preset`) are the points marked ★; `auto` walks between them one knob at a time "
              "(igserver/render/presets.py).", ""]
    for study in studies:
        plot = f"{study.pipeline}.png"
        plot_study(study, out_dir / plot)
        lines += study_markdown(study, plot)
    for name, reason in (failures or {}).items():
        lines += [f"## {name}", "", reason if reason.startswith("no study()") else f"Study failed: {reason}", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(lines))
    (out_dir / "report.json").write_text(json.dumps([s.to_dict() for s in studies], indent=1))
    return path


# -- igserver quality (no argument): every study, one report ------------------------------------------

def study_modules() -> list[str]:
    """Names of the modules in igserver/quality that are studies (have ``run``)."""
    import importlib
    import pkgutil

    from .. import quality

    names = []
    for info in pkgutil.iter_modules(quality.__path__):
        if info.name == "report":
            continue
        module = importlib.import_module(f"igserver.quality.{info.name}")
        if callable(getattr(module, "run", None)):
            names.append(info.name)
    return sorted(names)


def _study_in_subprocess(name: str, quick: bool, out_dir: Path, timeout_s: float) -> tuple[Study | None, str]:
    """Run one study in its own process (its own GL context and environment; a crash stays there)."""
    import subprocess

    json_path = out_dir / f"{name}.json"
    cmd = [sys.executable, "-m", "igserver.quality.report", "--one", name, "--json", str(json_path)]
    if quick:
        cmd.append("--quick")
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return None, f"timed out after {timeout_s:.0f} s"
    (out_dir / f"{name}.log").write_text(proc.stdout + proc.stderr)
    if proc.returncode != 0:
        return None, f"exit {proc.returncode}: {(proc.stderr or proc.stdout).strip().splitlines()[-1:]}"
    if not json_path.exists():
        return None, "ran its own CLI (no study() for the combined report yet)"
    data = json.loads(json_path.read_text())
    return Study(**{**data, "points": [Point(**p) for p in data["points"]]}), ""


def run_all(argv: list[str]) -> int:
    import argparse
    import time

    ap = argparse.ArgumentParser(prog="igserver quality", description="every pipeline's study, one report")
    ap.add_argument("--quick", action="store_true", help="each study's quick mode (minutes in all)")
    ap.add_argument("--out", default="out/quality", help="folder of report.md and the plots")
    ap.add_argument("--only", help="comma-separated study names (default: all)")
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds per study")
    args = ap.parse_args(argv)
    try:
        pyplot()  # before the studies (up to an hour each), not after them
    except ModuleNotFoundError as exc:
        print(f"igserver quality: {exc}", file=sys.stderr)
        return 2
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = args.only.split(",") if args.only else study_modules()
    studies, failures = [], {}
    start = time.perf_counter()
    import importlib

    for name in names:
        t0 = time.perf_counter()
        if args.quick and not callable(getattr(importlib.import_module(f"igserver.quality.{name}"), "study", None)):
            failures[name] = (f"no study() for the combined report yet; skipped in --quick "
                              f"(its own table: igserver quality {name})")
            print(f"quality: {name}: skipped (no study())", flush=True)
            continue
        print(f"quality: {name} ...", flush=True)
        study, reason = _study_in_subprocess(name, args.quick, out_dir, args.timeout)
        if study is None:
            failures[name] = reason
            print(f"quality: {name}: {reason}", flush=True)
        else:
            studies.append(study)
            print(f"quality: {name}: {len(study.points)} points in {time.perf_counter() - t0:.0f} s", flush=True)
    header = [f"Command: `igserver quality{' --quick' if args.quick else ''}` "
              f"({time.perf_counter() - start:.0f} s). Studies: {', '.join(names)}.", ""]
    path = write_report(studies, out_dir, failures, header)
    print(f"wrote {path}")
    return 0 if not [r for r in failures.values() if not r.startswith("no study()")] else 1


def _one(argv: list[str]) -> int:
    """Subprocess entry: run ``--one NAME``'s study() and write its JSON (or its run() when it has none)."""
    import argparse
    import importlib

    ap = argparse.ArgumentParser()
    ap.add_argument("--one", required=True)
    ap.add_argument("--json", required=True)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    module = importlib.import_module(f"igserver.quality.{args.one}")
    if callable(getattr(module, "study", None)):
        result = module.study(quick=args.quick)
        Path(args.json).write_text(json.dumps(result.to_dict()))
        return 0
    return module.run(["--quick"] if args.quick else []) or 0


if __name__ == "__main__":
    raise SystemExit(_one(sys.argv[1:]))
