"""Rendering quality of an episode's online map and of its offline refinements, like the paper's Tab. V
(post-processing ablation on Gibson-Denmark).

    python benchmarks/render.py EPISODE [--iters 2000] [--budget-min 30] [--methods 3dgs 2dgs]
                                [--n-train 50] [--n-test 50] [--backend auto]

EPISODE: a complete episode folder (the README's numbers: a 1000-step small-0 episode of
`activesplat explore --scene small-0`).

1. **online**: ``render_eval`` of EPISODE/gaussians.ply (EPISODE/render_metrics.json).
2. **short refinement**: for each method, ``refine(EPISODE, method, --iters)`` into
   EPISODE/refined_<method>_<iters>/ (its gaussians.ply, render_metrics.json, refine.json).
3. **long refinement**: for each method, as many iterations as fit in ``--budget-min`` minutes at the
   speed the short run measured (capped at the paper's 30,000, rounded down to hundreds; skipped when
   that is not more than ``--iters``), into EPISODE/refined_<method>_<N>/.

Everything is resumable: a finished step is read back from its folder, an interrupted refinement
continues from its checkpoint. Prints a markdown table (train / test PSNR, SSIM, LPIPS, depth L1 per
map) followed by the paper's rows for orientation (different scenes, GPU, 512x512, 30k iterations).
Timings are wall-clock on whatever else the machine is doing.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from activesplat.eval.render_eval import render_eval
from activesplat.refine import refine

PAPER_ITERATIONS = 30_000
# Tab. V of the paper, with depth loss: (train, test) x (depth L1 cm, PSNR, SSIM, LPIPS)
PAPER = {
    "online": ((1.91, 25.28, 0.83, 0.22), (9.01, 21.72, 0.76, 0.29)),
    "3dgs @ 30k": ((0.77, 38.90, 0.99, 0.03), (7.81, 26.87, 0.88, 0.17)),
    "2dgs @ 30k": ((0.80, 38.90, 0.99, 0.04), (7.56, 27.58, 0.88, 0.17)),
}


def online_metrics(episode: Path, args) -> dict:
    path = episode / "render_metrics.json"
    if path.is_file():
        metrics = json.loads(path.read_text())
        if metrics["train"]["n_views"] == args.n_train and metrics["test"]["n_views"] == args.n_test:
            return metrics
    return render_eval(episode, n_train=args.n_train, n_test=args.n_test, backend=args.backend,
                       progress=not args.no_progress)


def refined(episode: Path, method: str, iters: int, args) -> dict:
    """Refine (or read back) ``iters`` iterations of ``method``; returns a row of the table."""
    out = episode / f"refined_{method}_{iters}"
    t0 = time.perf_counter()
    res = refine(episode, method, iters, backend=args.backend, progress=not args.no_progress, out_dir=out,
                 eval_kwargs={"n_train": args.n_train, "n_test": args.n_test})
    info = json.loads((out / "refine.json").read_text())
    return {"name": f"{method} @ {iters}", "metrics": res.metrics, "n_gaussians": res.n_gaussians,
            "train_s": res.train_seconds, "rate": info["iterations_per_second"],
            "eval_renderer": info.get("eval_renderer", ""), "session_s": time.perf_counter() - t0}


def long_iterations(rate: float | None, budget_min: float, short: int) -> int | None:
    """Iterations that fit in the budget at ``rate`` it/s (hundreds, at most 30k); None if not > short."""
    if not rate or budget_min <= 0:
        return None
    n = min(PAPER_ITERATIONS, int(rate * budget_min * 60.0) // 100 * 100)
    return n if n > short else None


def _fmt(value, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def table(rows: list[dict]) -> str:
    head = ("| map | Gaussians | refine min | train PSNR | train SSIM | train LPIPS | train depth L1 cm "
            "| test PSNR | test SSIM | test LPIPS | test depth L1 cm | test unmapped % |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for row in rows:
        m = row["metrics"] or {}
        minutes = row["train_s"] / 60.0 if row.get("train_s") else None
        cells = [row["name"], f"{row['n_gaussians']:,}", _fmt(minutes, ".1f")]
        for split in ("train", "test"):
            s = m.get(split, {})
            cells += [_fmt(s.get("psnr"), ".2f"), _fmt(s.get("ssim"), ".3f"), _fmt(s.get("lpips"), ".3f"),
                      _fmt(s.get("depth_l1_cm"), ".2f")]
        cells.append(_fmt(m.get("test", {}).get("unmapped_pct"), ".1f"))
        lines.append("| " + " | ".join(cells) + " |")
    for name, (train, test) in PAPER.items():
        cells = [f"paper (Gibson-Denmark) {name}", "", ""]
        for depth, psnr, ssim, lpips in (train, test):
            cells += [f"{psnr:.2f}", f"{ssim:.2f}", f"{lpips:.2f}", f"{depth:.2f}"]
        cells.append("")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("episode", help="complete episode folder")
    parser.add_argument("--iters", type=int, default=2000, help="iterations of the short refinements")
    parser.add_argument("--budget-min", type=float, default=30.0,
                        help="minutes per method for the long refinement (0 = none)")
    parser.add_argument("--methods", nargs="+", default=["3dgs", "2dgs"], choices=["3dgs", "2dgs"])
    parser.add_argument("--n-train", type=int, default=50)
    parser.add_argument("--n-test", type=int, default=50)
    parser.add_argument("--backend", default="auto", choices=("auto", "numba", "torch", "gsplat"))
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args()
    episode = Path(args.episode)
    if not (episode / "metrics.json").is_file():
        raise SystemExit(f"{episode}: not a complete episode (no metrics.json yet)")

    online = online_metrics(episode, args)
    rows = [{"name": "online", "metrics": online, "n_gaussians": online["n_gaussians"]}]
    short = {m: refined(episode, m, args.iters, args) for m in args.methods}
    rows += list(short.values())
    notes = []
    for method, row in short.items():
        n = long_iterations(row["rate"], args.budget_min, args.iters)
        if n is not None:
            rows.append(refined(episode, method, n, args))
        elif args.budget_min > 0:
            fit = int((row["rate"] or 0.0) * args.budget_min * 60.0)
            notes.append(f"{method}: no longer run, {args.budget_min:g} min at {row['rate']:.2f} it/s fit "
                         f"~{fit} iterations, not more than --iters {args.iters}")
    print(f"\n{episode}: {args.n_train} train / {args.n_test} test views\n")
    print(table(rows))
    print()
    for row in rows[1:]:
        print(f"{row['name']}: {row['rate']:.2f} it/s over {row['train_s'] / 60:.1f} min of optimisation; "
              f"evaluated with the {row['eval_renderer']}")
    for note in notes:
        print(note)


if __name__ == "__main__":
    main()
