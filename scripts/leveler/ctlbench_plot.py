"""The controller scorecard's figures: one PNG per scenario with algorithms 1, 2
and 3 side by side (height against the band, and each algorithm's outputs),
and the limit's trajectory (``DIR/<scenario>-limit.csv``, the best single move
per step) beside them when its log is there.

    python -m leveler.ctlbench_plot --dir build/ctlbench --configs host_sim/configs [SCENARIO ...]

Reads ``DIR/scorecard.json`` (written by ``leveler-ctlbench``) and the run logs
``DIR/<scenario>-alg<N>.csv`` through :mod:`leveler.runlog`; writes
``DIR/<scenario>.png`` atomically. Without scenario names, every scenario of the
scorecard is drawn.
"""

from __future__ import annotations

import io
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from . import cli  # noqa: E402
from . import config as config_mod  # noqa: E402
from . import plot as plot_mod  # noqa: E402
from . import runlog, thesis  # noqa: E402

ALGORITHMS = (1, 2, 3)
LIMIT = "limit"
COLORS = {1: "#7f7f7f", 2: "#ff7f0e", 3: "#1f77b4", LIMIT: "#000000"}


def _title(scenario):
    runs = {r["algorithm"]: r for r in scenario["runs"]}
    parts = [f"alg {a}: return median {runs[a]['return_median_s']:.1f} s, "
             f"{runs[a]['switchings_per_step']:.1f} sw/step" for a in ALGORITHMS if a in runs]
    return f"{scenario['name']} (noise {scenario['noise_counts']:g} counts)\n" + "; ".join(parts)


def plot_scenario(directory, configs_dir, scenario):
    """Draws one scenario's three runs into DIR/<name>.png."""
    cfg = config_mod.load(os.path.join(configs_dir, scenario["config"]))
    logs = {a: runlog.read(os.path.join(directory, f"{scenario['name']}-alg{a}.csv")) for a in ALGORITHMS}
    limit_path = os.path.join(directory, f"{scenario['name']}-limit.csv")
    if os.path.exists(limit_path):
        logs[LIMIT] = runlog.read(limit_path)
    runs = [a for a in (*ALGORITHMS, LIMIT) if a in logs]
    fig, axes = plt.subplots(1 + len(runs), 1, figsize=(11, 8.5 + (len(runs) - 3) * 1.2), sharex=True,
                             gridspec_kw={"height_ratios": [3] + [1] * len(runs)})
    ax_h = axes[0]
    ax_h.axhspan(cfg.band_lower_m / thesis.M_PER_IN, cfg.band_upper_m / thesis.M_PER_IN,
                 color="#2ca02c", alpha=0.15, lw=0, label="band")
    for a in runs:
        ax_h.plot(logs[a].t_s, logs[a].height_m / thesis.M_PER_IN, color=COLORS[a], lw=1.0,
                  ls="--" if a == LIMIT else "-", label="limit (best single move)" if a == LIMIT else f"algorithm {a}")
    ax_h.set_ylabel("height (in)")
    ax_h.legend(loc="upper right", fontsize=8)
    ax_h.set_title(_title(scenario), fontsize=9)
    for ax, a in zip(axes[1:], runs):
        log = logs[a]
        for k, (name, label, color) in enumerate(plot_mod._ACTUATORS):
            if name not in runlog.ACTUATORS:
                continue
            on = log.column(name) > 0.5
            spans = [(log.t_s[s], log.t_s[min(s + n, len(log) - 1)] - log.t_s[s]) for s, n in plot_mod._runs(on)]
            ax.broken_barh(spans, (k + 0.1, 0.8), color=color, label=label if a == 1 else None)
        ax.set_yticks([])
        ax.set_ylabel("limit" if a == LIMIT else f"alg {a}", rotation=0, labelpad=18)
    axes[1].legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    out = os.path.join(directory, f"{scenario['name']}.png")
    runlog.write_text_atomic(out, buf.getvalue(), mode="wb")
    return out


def main(argv=None):
    ap = cli.parser("python -m leveler.ctlbench_plot", __doc__.splitlines()[0])
    ap.add_argument("--dir", required=True, help="the scorecard folder (scorecard.json and the run logs)")
    ap.add_argument("--configs", required=True, help="the folder of the INI files")
    ap.add_argument("scenarios", nargs="*", help="scenario names (default: all)")
    args = ap.parse_args(argv)
    path = os.path.join(args.dir, "scorecard.json")
    try:
        with open(path, encoding="utf-8") as f:
            card = json.load(f)
    except (OSError, ValueError) as e:
        print(f"ctlbench_plot: {path}: {e}", file=sys.stderr)
        return 1
    wanted = set(args.scenarios)
    for scenario in card["scenarios"]:
        if wanted and scenario["name"] not in wanted:
            continue
        try:
            print(f"ctlbench_plot: {plot_scenario(args.dir, args.configs, scenario)}")
        except (OSError, ValueError) as e:
            print(f"ctlbench_plot: {scenario['name']}: {e}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
