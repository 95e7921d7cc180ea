"""Paired comparison of two benchmark roots (or two policies of one root): run by run, the same scene and
seed on both sides, and the mean difference with its paired standard error.

    activesplat compare runs/defaults runs/my-rule
    activesplat compare runs/benchmark runs/benchmark --base-policy no-hp      # no-hp -> activesplat

One run of a medium house moves by a point or two when any rule changes its route, so a difference between
two batches means something only next to its spread (docs/benchmark.md, "How large a difference one batch
can show"). The table pairs every run of NEW with the run of BASE of the same scene and seed, prints both
sides of each measure and the difference of the completion, and ends with the mean difference, its
standard error (the standard deviation of the paired differences over the square root of their number),
and how many runs are higher, lower, or the same (completion within 0.005 points); runs whose action
logs are byte for byte the same are marked. With a scene's sweep ceiling (ROOT/<scene>/sweep.json as
`activesplat benchmark` caches it, in either root or in `--ceilings DIR`) it adds the share of the ceiling
and the worst room against the room's own ceiling; without one, the worst room is the lowest share of a
room's own points.
Runs with a render_metrics.json (`activesplat render-eval`) add the test and train PSNR, the test LPIPS
and depth L1 of their maps. The mean row averages each measure over the pairs that have it on both sides
(and says how many when not all), so that BASE's and NEW's means are over the same runs.
Settings of the runs' episode.json that differ between the sides are listed above the table.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from activesplat.bench.runner import read_metrics
from activesplat.errors import InvalidInputError, cannot_write, check_output_file

SAME_TOL_PCT = 0.005
"""Completion differences smaller than this (percentage points) count as the same."""


@dataclass
class Pair:
    """The run of one scene and seed on both sides."""

    scene: str
    seed: int
    base: dict
    new: dict
    same_actions: bool | None
    """Whether both action logs are byte for byte the same (None: a log is missing)."""
    base_render: dict | None = None
    new_render: dict | None = None
    """The runs' render_metrics.json (`activesplat render-eval`), where there is one."""
    base_settings: dict | None = None
    new_settings: dict | None = None
    """The runs' settings (episode.json's config, flattened to GROUP.FIELD), where recorded."""

    @property
    def delta(self) -> float:
        return float(self.new["completion_ratio_pct"]) - float(self.base["completion_ratio_pct"])


def find_runs(root: str | Path, policy: str) -> dict[tuple[str, int], tuple[Path, dict]]:
    """The complete runs of `policy` under a root (ROOT/<scene>/<policy>/s<seed>), by (scene, seed): each
    run's folder and its metrics."""
    root = Path(root)
    if not root.is_dir():
        raise InvalidInputError(f"no such benchmark folder: {root}")
    runs = {}
    for out in sorted(root.glob(f"*/{policy}/s*")):
        metrics = read_metrics(out) if out.is_dir() and out.name[1:].isdigit() else None
        if metrics is not None:
            runs[(out.parent.parent.name, int(out.name[1:]))] = (out, metrics)
    return runs


def _policies(root: Path) -> list[str]:
    return sorted({p.parent.parent.name for p in root.glob("*/*/s*/metrics.json")})


def _same_actions(a: Path, b: Path) -> bool | None:
    fa, fb = a / "actions.txt", b / "actions.txt"
    if not (fa.is_file() and fb.is_file()):
        return None
    return fa.read_bytes() == fb.read_bytes()


def pair_runs(base_root: str | Path, new_root: str | Path, policy: str = "activesplat",
              base_policy: str | None = None) -> tuple[list[Pair], list[str]]:
    """The runs of `policy` in NEW paired with those of `base_policy` (default the same) in BASE, by scene and
    seed, and a line for each run found on one side only. Raises when nothing pairs, or when a pair's step
    budgets differ."""
    base_policy = base_policy or policy
    base, new = find_runs(base_root, base_policy), find_runs(new_root, policy)
    if not base or not new:
        side, root, pol = (("BASE", base_root, base_policy) if not base else ("NEW", new_root, policy))
        found = ", ".join(_policies(Path(root))) or "none"
        raise InvalidInputError(f"{side} ({root}) holds no complete run of policy {pol!r} "
                                f"(policies with complete runs there: {found})")
    keys = sorted(set(base) & set(new))
    if not keys:
        raise InvalidInputError(f"no scene and seed is in both: BASE has {_names(base)}, "
                                f"NEW has {_names(new)}")
    pairs = []
    for scene, seed in keys:
        (b_out, b), (n_out, n) = base[(scene, seed)], new[(scene, seed)]
        if b.get("steps") != n.get("steps"):
            raise InvalidInputError(f"{scene} seed {seed}: BASE ran {b.get('steps')} steps and NEW "
                                    f"{n.get('steps')}; compare runs of the same budget")
        pairs.append(Pair(scene, seed, b, n, _same_actions(b_out, n_out), _render_metrics(b_out),
                          _render_metrics(n_out), _settings(b_out), _settings(n_out)))
    unpaired = [f"only in BASE: {s} seed {d}" for s, d in sorted(set(base) - set(new))]
    unpaired += [f"only in NEW: {s} seed {d}" for s, d in sorted(set(new) - set(base))]
    return pairs, unpaired


def _render_metrics(out: Path) -> dict | None:
    path = out / "render_metrics.json"
    try:
        return json.loads(path.read_text()) if path.is_file() else None
    except ValueError:
        return None


RUN_KEYS = ("version", "scene", "policy", "seed", "steps")
"""Recorded settings that name the run rather than configure it (pairs share scene, seed and steps)."""


def _settings(out: Path) -> dict | None:
    """A run's recorded configuration as GROUP.FIELD -> value, without what names the run."""
    from activesplat.bench.runner import _flat
    from activesplat.episode import read_meta
    from activesplat.errors import EpisodeError

    try:
        config = read_meta(out).get("config")
    except EpisodeError:
        return None
    return {k: v for k, v in _flat(config).items() if k not in RUN_KEYS} if isinstance(config, dict) else None


def differing_settings(pairs: list[Pair]) -> list[str]:
    """'GROUP.FIELD base -> new' for each setting recorded on both sides of some pair with other values."""
    found: dict[str, list[str]] = {}
    for p in pairs:
        b, n = p.base_settings or {}, p.new_settings or {}
        for key in sorted(set(b) & set(n)):
            text = f"{b[key]!r} → {n[key]!r}"
            if b[key] != n[key] and text not in found.setdefault(key, []):
                found[key].append(text)
    return [f"{key} {', '.join(values)}" for key, values in sorted(found.items()) if values]


def _names(runs: dict) -> str:
    return ", ".join(f"{s} s{d}" for s, d in sorted(runs)) or "nothing"


def read_ceilings(scenes, roots) -> dict[str, dict]:
    """Each scene's sweep ceiling from the first of `roots` that holds <root>/<scene>/sweep.json."""
    out = {}
    for scene in scenes:
        for root in roots:
            path = Path(root) / scene / "sweep.json"
            if path.is_file():
                try:
                    found = json.loads(path.read_text())
                except ValueError as exc:
                    raise InvalidInputError(f"{path} is not a sweep ceiling (JSON: {exc})") from exc
                if not isinstance(found, dict) or "completion_ratio_pct" not in found:
                    raise InvalidInputError(f"{path} is not a sweep ceiling (no completion_ratio_pct)")
                out[scene] = found
                break
    return out


def at_step(metrics: dict, step: int) -> float | None:
    """Completion ratio (%) of the curve's last point at or before `step` (None: no curve there)."""
    points = [c for c in metrics.get("curve") or [] if c["step"] <= step]
    return float(points[-1]["completion_ratio_pct"]) if points else None


def _measures(metrics: dict, ceiling: dict | None, render: dict | None = None) -> dict:
    """The compared measures of one run (`render`: its render_metrics.json); None where the run does not
    have one."""
    from activesplat.eval.behaviour import relative_to_ceiling

    steps = int(metrics.get("steps") or 0)
    half = at_step(metrics, steps // 2) if steps else None
    out = {"completion": metrics["completion_ratio_pct"], "half": half,
           "rotations": metrics.get("rotation_pct"), "path": metrics.get("path_length_m"),
           "rooms": metrics.get("rooms_entered"), "of_ceiling": None, "half_of_ceiling": None, "worst": None}
    rooms = (metrics.get("rooms") or {}).get("completion") or {}
    shares = [r["completion_ratio_pct"] for r in rooms.values() if r.get("completion_ratio_pct") is not None]
    if shares:
        out["worst"] = min(shares)
    if ceiling is not None:
        rel = relative_to_ceiling(metrics, ceiling)
        top = float(ceiling["completion_ratio_pct"])
        out["of_ceiling"] = rel.get("of_ceiling_pct")
        out["half_of_ceiling"] = None if half is None or top <= 0 else 100.0 * half / top
        out["worst"] = rel.get("worst_room_of_ceiling_pct", out["worst"])
    for split in ("test", "train"):
        for key in ("psnr", "lpips", "depth_l1_cm"):
            out[f"{split}_{key}"] = ((render or {}).get(split) or {}).get(key)
    return out


COLUMNS = (("completion", "completion %", 2), ("of_ceiling", "of ceiling %", 1),
           ("half", "at half the steps %", 2), ("half_of_ceiling", "at half, of ceiling %", 1),
           ("rotations", "rotations %", 1), ("path", "path m", 1), ("rooms", "rooms entered", 0),
           ("worst", "worst room %", 1), ("test_psnr", "test PSNR dB", 2), ("test_lpips", "test LPIPS", 3),
           ("test_depth_l1_cm", "test depth L1 cm", 2), ("train_psnr", "train PSNR dB", 2))
"""(measure, column, decimals) of the comparison table; a column no run has is left out."""


def _fmt(v, d: int) -> str:
    return "n/a" if v is None else f"{v:.{d}f}"


def _signed(v: float) -> str:
    """+1.23 / -1.23, and +0.00 for what rounds to zero (no "-0.00")."""
    return f"{v if round(v, 2) else 0.0:+.2f}"


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _paired_mean(rows: list[tuple[Pair, dict, dict]], key: str, decimals: int) -> str:
    """The mean row's cell of one measure: BASE's mean → NEW's mean over the pairs where both sides have
    it (a run without render-eval leaves its pair out of the render columns on both sides, so the two
    means cover the same runs), and how many pairs that is when not all."""
    both = [(b[key], n[key]) for _, b, n in rows if b[key] is not None and n[key] is not None]
    if not both:
        return "n/a"
    d = decimals or 2  # counts (rooms entered) average to fractions
    cell = f"{_fmt(_mean(v for v, _ in both), d)} → {_fmt(_mean(v for _, v in both), d)}"
    return cell if len(both) == len(rows) else f"{cell} ({len(both)} of {len(rows)})"


def compare_report(pairs: list[Pair], ceilings: dict[str, dict] | None = None, base_name: str = "BASE",
                   new_name: str = "NEW", unpaired: list[str] | None = None) -> str:
    """Markdown: one row per pair (BASE -> NEW for each measure, the completion's difference), the means,
    and the summary of the completion's differences."""
    ceilings = ceilings or {}
    rows = [(p, _measures(p.base, ceilings.get(p.scene), p.base_render),
             _measures(p.new, ceilings.get(p.scene), p.new_render)) for p in pairs]
    cols = [c for c in COLUMNS if any(b[c[0]] is not None or n[c[0]] is not None for _, b, n in rows)]
    head = ["scene", "seed", *(name for _, name, _ in cols), "Δ completion", "same actions"]
    lines = [f"# {new_name} against {base_name}", "",
             "Each cell: BASE → NEW. Worst room: "
             + ("the lowest share of a room's own sweep ceiling." if ceilings else
                "the lowest share of a room's own points (no sweep ceiling found)."), "",
             *([f"Settings that differ (BASE → NEW): {'; '.join(differ)}.", ""]
               if (differ := differing_settings(pairs)) else []),
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p, b, n in rows:
        same = {True: "yes", False: "no", None: "n/a"}[p.same_actions]
        lines.append("| " + " | ".join([p.scene, str(p.seed),
                                        *(f"{_fmt(b[k], d)} → {_fmt(n[k], d)}" for k, _, d in cols),
                                        _signed(p.delta), same]) + " |")
    means = [_paired_mean(rows, k, d) for k, _, d in cols]
    deltas = np.array([p.delta for p in pairs])
    mean_row = [f"**mean of {len(pairs)}**", "", *means, f"**{_signed(deltas.mean())}**", ""]
    lines.append("| " + " | ".join(mean_row) + " |")
    same = [abs(p.delta) < SAME_TOL_PCT for p in pairs]
    higher = sum(1 for p, s in zip(pairs, same, strict=True) if not s and p.delta > 0)
    lower = sum(1 for p, s in zip(pairs, same, strict=True) if not s and p.delta < 0)
    se = float(deltas.std(ddof=1) / math.sqrt(len(deltas))) if len(deltas) > 1 else None
    identical = sum(1 for p, s in zip(pairs, same, strict=True) if s and p.same_actions)
    lines += ["", f"Completion, NEW − BASE: **{_signed(deltas.mean())} points** (paired standard error "
              f"{_fmt(se, 2)}; {higher} higher, {lower} lower, {sum(same)} the same"
              f"{f', {identical} of them with the same actions' if identical else ''}"
              f"); lowest {_signed(deltas.min())}, highest {_signed(deltas.max())}."]
    if se is not None and se > 0:
        lines.append(f"The mean difference is {abs(deltas.mean()) / se:.1f} standard errors from zero.")
    if unpaired:
        lines += ["", "Not compared: " + "; ".join(unpaired) + "."]
    return "\n".join(lines) + "\n"


def compare_from_args(args) -> int:
    """`activesplat compare BASE NEW` (argparse namespace: base, new, policy, base_policy, ceilings, out)."""
    if args.out:  # before the report is printed (missing folders above it are made)
        check_output_file(args.out, "--out")
    pairs, unpaired = pair_runs(args.base, args.new, args.policy, args.base_policy)
    roots = [args.new, args.base, *([args.ceilings] if args.ceilings else [])]
    ceilings = read_ceilings({p.scene for p in pairs}, roots)
    base_name = f"{args.base} ({args.base_policy or args.policy})"
    report = compare_report(pairs, ceilings, base_name, f"{args.new} ({args.policy})", unpaired)
    print(report, end="")
    if args.out:
        try:
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.out).write_text(report, encoding="utf-8")
        except OSError as exc:
            raise cannot_write(args.out, exc, "--out") from None
    return 0


__all__ = ["Pair", "at_step", "compare_from_args", "compare_report", "differing_settings", "find_runs",
           "pair_runs", "read_ceilings"]
