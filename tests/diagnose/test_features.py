"""--features: published event figures instead of traces (the thesis experiment)."""
import json
import os

import numpy as np
import pytest

from leveler import thesis
from leveler.diagnose import cli, features

HERE = os.path.dirname(os.path.abspath(__file__))
THESIS = os.path.join(HERE, "..", "..", "scripts", "leveler", "diagnose", "data", "thesis-experiment.json")


def write(tmp_path, doc):
    p = tmp_path / "f.json"
    p.write_text(json.dumps(doc))
    return str(p)


def good_runs():
    return [{"name": "a", "config": "thesis-900lb", "role": "calibration",
             "features": {"lowest_height_m": 0.3708}},
            {"name": "b", "config": "thesis-1000lb", "role": "holdout",
             "features": {"lowest_height_m": 0.3683}}]


@pytest.mark.parametrize("mutate, expect", [
    (lambda r: r[0]["features"].update(lowest_height_in=14.6), "features.lowest_height_in: unknown figure"),
    (lambda r: r[0]["features"].update(lowest_height_m=14.6), "features.lowest_height_m = 14.6 is outside"),
    (lambda r: r[1].update(role="calibration"), "need at least one calibration and one holdout"),
    (lambda r: r[0].update(schedule={"step_at": 5}), "schedule.step_at: unknown key"),
])
def test_bad_features_file_is_named(tmp_path, mutate, expect):
    runs = good_runs()
    mutate(runs)
    p = write(tmp_path, {"runs": runs})
    with pytest.raises(features.DiagnoseInputError) as e:
        features.load(p, "thesis-900lb")
    assert expect in str(e.value) and "f.json" in str(e.value)


def test_the_shipped_thesis_file_is_the_readme_table():
    with open(THESIS) as fh:
        doc = json.load(fh)
    by_name = {r["name"]: r for r in doc["runs"]}
    for case in ("thesis-900lb-exp", "thesis-1000lb-exp"):
        want = {k: v for k, v in thesis.CASES[case].items() if v is not None}
        assert by_name[case]["features"] == pytest.approx(want)
    # 14.6 in lowest, 19 s at the bottom (900 lb experiment)
    f = by_name["thesis-900lb-exp"]["features"]
    assert f["lowest_height_m"] == pytest.approx(14.6 * 0.0254)
    assert f["time_stuck_bottom_s"] == 19


ACCUMULATOR = os.path.join(os.path.dirname(THESIS), "thesis-accumulator.json")


def test_the_shipped_accumulator_file_is_the_readme_list(cplant):
    with open(ACCUMULATOR) as fh:
        doc = json.load(fh)
    by_name = {r["name"]: r for r in doc["runs"]}
    # README: 90 psig drop to 14.9 in; 112 psig return in about 2 s; 1000 lb 100 psig 14.82 in, 2.5 s
    assert by_name["thesis-900lb-acc90psig-exp"]["features"]["lowest_height_m"] == pytest.approx(14.9 * 0.0254)
    assert by_name["thesis-900lb-acc112psig-exp"]["features"]["time_return_after_step_s"] == 2.0
    f = by_name["thesis-1000lb-acc100psig-exp"]["features"]
    assert f["lowest_height_m"] == pytest.approx(14.82 * 0.0254) and f["time_return_after_step_s"] == 2.5
    # each run's config starts the accumulator at the charge its case names (the C plant's word)
    t = np.round(np.arange(0.0, 0.05, 0.01), 2)
    for name, r in by_name.items():
        assert r["config"].split("lb")[0] in name
        tr = cplant.generate(r["config"], t, np.full(len(t), 4000.0), None, [])
        assert tr.signals["p_acc_pa"][0] == pytest.approx(thesis.ACCUMULATOR_CHARGE_PA[name], abs=1.0)


def test_features_run_end_to_end(cplant, tmp_path, capsys):
    out = tmp_path / "out"
    rc = cli.main(["--config", "thesis-900lb", "--features", THESIS, "--out", str(out), "--quiet",
                   "--effects", "thermal,leak", "--fast", "--jobs", "1"])
    assert rc == 0, capsys.readouterr().err
    d = json.loads((out / "diagnosis.json").read_text())
    figures = {(w["run"], w["figure"]) for w in d["where"]["ranked"]}
    assert ("thesis-900lb-exp", "time_stuck_bottom_s") in figures
    assert d["gap_before"]["normalised"] > 0
    assert d["effect"] in ("thermal", "leak", "none")
    assert {r["effect"] for r in d["ranking"]} == {"thermal", "leak"}


def test_flat_summaries_in_two_files(tmp_path):
    """A flat leveler.events summary per file: the first calibrates, the second is held out."""
    a = tmp_path / "exp900.json"
    a.write_text(json.dumps({"config": "thesis-900lb", "lowest_height_m": 0.3708, "time_stuck_bottom_s": 19}))
    b = tmp_path / "exp1000.json"
    b.write_text(json.dumps({"config": "thesis-1000lb", "lowest_height_m": 0.3683}))
    calib, hold = features.load_many([str(a), str(b)], "thesis-900lb")
    assert [r.name for r in calib] == ["exp900"] and [r.name for r in hold] == ["exp1000"]
    assert calib[0].features == {"lowest_height_m": 0.3708, "time_stuck_bottom_s": 19.0}
    assert hold[0].config_override == "thesis-1000lb"
    with pytest.raises(features.DiagnoseInputError, match="need at least one calibration and one holdout"):
        features.load_many([str(a)], "thesis-900lb")
