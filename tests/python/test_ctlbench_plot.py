"""python -m leveler.ctlbench_plot: one PNG per scenario from the scorecard and its logs."""

import json
import os

import synth
from leveler import ctlbench_plot, runlog

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIGS = os.path.join(ROOT, "host_sim", "configs")


def _scorecard(directory, names):
    runs = [{"algorithm": a, "return_median_s": 10.0 * a, "switchings_per_step": float(a)} for a in (1, 2, 3)]
    card = {"scenarios": [{"name": n, "config": "thesis-900lb.ini", "noise_counts": 2, "runs": runs} for n in names]}
    (directory / "scorecard.json").write_text(json.dumps(card))
    for n in names:
        for a in (1, 2, 3):
            runlog.write(directory / f"{n}-alg{a}.csv", synth.make_log())


def test_draws_each_scenario(tmp_path, capsys):
    _scorecard(tmp_path, ["one", "two"])
    assert ctlbench_plot.main(["--dir", str(tmp_path), "--configs", CONFIGS]) == 0
    for n in ("one", "two"):
        with open(tmp_path / f"{n}.png", "rb") as f:
            assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    assert "two.png" in capsys.readouterr().out


def test_only_the_named_scenario(tmp_path):
    _scorecard(tmp_path, ["one", "two"])
    assert ctlbench_plot.main(["--dir", str(tmp_path), "--configs", CONFIGS, "two"]) == 0
    assert (tmp_path / "two.png").exists() and not (tmp_path / "one.png").exists()


def test_errors_name_the_file(tmp_path, capsys):
    assert ctlbench_plot.main(["--dir", str(tmp_path), "--configs", CONFIGS]) == 1
    assert "scorecard.json" in capsys.readouterr().err
    _scorecard(tmp_path, ["one"])
    os.remove(tmp_path / "one-alg2.csv")
    assert ctlbench_plot.main(["--dir", str(tmp_path), "--configs", CONFIGS]) == 1
    assert "one" in capsys.readouterr().err


def _png_height(path):
    with open(path, "rb") as f:
        head = f.read(24)
    return int.from_bytes(head[20:24], "big")


def test_the_limit_drawn_when_its_log_is_there(tmp_path):
    _scorecard(tmp_path, ["one", "two"])
    runlog.write(tmp_path / "two-limit.csv", synth.make_log())
    assert ctlbench_plot.main(["--dir", str(tmp_path), "--configs", CONFIGS]) == 0
    # the limit's outputs get a fifth panel: the figure is taller than the one without it
    assert _png_height(tmp_path / "two.png") > _png_height(tmp_path / "one.png")
