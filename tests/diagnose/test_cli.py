"""The CLI on bad input: clear errors naming file, line and field; nothing
half-written to --out. And a whole run on the test-only stand-in plant."""
import json
import os
import stat

import numpy as np
import pytest

from conftest import thesis_schedule
from leveler.diagnose import cli, runs
from standin import StandIn

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SIM = ["--simulator", "standin:StandIn"]


def make_logs(folder, effect=None, params=None, seed=0):
    sim = StandIn()
    rng = np.random.default_rng(seed)
    paths = []
    for i, (on, off, step) in enumerate([(5, 35, 200), (4, 31, 250), (6, 33, 150)]):
        t, load = thesis_schedule(end=50.0, on=on, off=off, step_lb=step)
        tr = sim.generate("toy", t, load, effect, params or {}, 0)
        sig = dict(tr.signals)
        sig["height_m"] = sig["height_m"] + rng.normal(0, 0.05e-3, len(t))
        sig["p_spring_pa"] = sig["p_spring_pa"] + rng.normal(0, 200.0, len(t))
        p = os.path.join(folder, f"run{i}.csv")
        runs.write_run(p, t, sig, load, tr.commands, "toy", "rig")
        paths.append(p)
    return paths


def args(paths, out, *extra):
    return ["--config", "toy", "--run", paths[0], "--run", paths[1], "--holdout", paths[2],
            "--out", str(out), "--quiet", "--jobs", "1"] + SIM + list(extra)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("logs")
    return make_logs(str(d), "sensor_lag", {"tau_pressure_s": 0.5, "p_offset_pa": 4000.0})


def rewrite(src, dst, fn):
    with open(src) as fh:
        lines = fh.read().splitlines()
    with open(dst, "w") as fh:
        fh.write("\n".join(fn(lines)) + "\n")


def run_cli(argv, capsys):
    rc = cli.main(argv)
    return rc, capsys.readouterr().err


def test_missing_column_names_file_line_and_column(logs, tmp_path, capsys):
    bad = str(tmp_path / "bad.csv")
    rewrite(logs[0], bad, lambda ls: [l if not l.startswith("t_s") else l.replace("height_m,", "")
                                      for l in ls])
    out = tmp_path / "out"
    rc, err = run_cli(args([bad, logs[1], logs[2]], out), capsys)
    assert rc == 2
    assert "bad.csv:4" in err and "height_m" in err and "missing" in err
    assert not out.exists()


def test_time_going_backwards_names_the_line(logs, tmp_path, capsys):
    bad = str(tmp_path / "back.csv")

    def swap(ls):
        ls[100], ls[101] = ls[101], ls[100]       # two data rows out of order
        return ls
    rewrite(logs[0], bad, swap)
    out = tmp_path / "out"
    rc, err = run_cli(args([bad, logs[1], logs[2]], out), capsys)
    assert rc == 2
    assert "back.csv:102" in err and "t_s" in err
    assert not out.exists()


def test_height_in_inches_is_called_out(logs, tmp_path, capsys):
    bad = str(tmp_path / "inches.csv")

    def to_inches(ls):
        out = []
        for l in ls:
            c = l.split(",")
            if l[0].isdigit():
                c[1] = repr(float(c[1]) / 0.0254)
            out.append(",".join(c))
        return out
    rewrite(logs[0], bad, to_inches)
    rc, err = run_cli(args([bad, logs[1], logs[2]], tmp_path / "out"), capsys)
    assert rc == 2 and "inches.csv:" in err and "inches" in err and "height_m" in err


def test_unknown_config(logs, tmp_path, capsys):
    a = args(logs, tmp_path / "out")
    a[a.index("toy")] = "no-such-config"
    rc, err = run_cli(a, capsys)
    assert rc == 2 and "no-such-config" in err and "toy" in err
    assert not (tmp_path / "out").exists()


def test_whole_run_names_the_effect_and_writes_atomically(logs, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "diagnosis.json").write_text("{\"from\": \"an earlier run\"}")   # an earlier output of its own
    rc, err = run_cli(args(logs, out, "--effects", "leak,sensor_lag", "--fast"), capsys)
    assert rc == 0, err
    d = json.loads((out / "diagnosis.json").read_text())
    for key in ("where", "ranking", "effect", "gap_before", "gap_after", "shrink_pct"):
        assert key in d
    assert d["effect"] == "sensor_lag"
    assert d["shrink_pct"] > 50.0
    assert d["ranking"][0]["params"]["tau_pressure_s"]["lo"] == 0.0
    assert abs(d["ranking"][0]["params"]["tau_pressure_s"]["value"] - 0.5) < 0.15
    assert "from" not in d                                       # the earlier output replaced
    assert [p for p in os.listdir(tmp_path) if p.startswith(".diagnose-")] == []
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html and "sensor_lag" in html
    version = open(os.path.join(ROOT, "VERSION")).read().strip()          # issue 22: traceable to the code
    assert d["version"] == version and f"leveler {version}" in html
    assert "<h2>Verdict: <code>sensor_lag</code></h2>" in html and "<td>leak</td>" in html


def test_out_folder_and_files_follow_the_umask(logs, tmp_path, capsys):
    """Issue 22: the diagnosis folder is made as mkdir would (not 0700 whatever the umask)."""
    old = os.umask(0o022)
    try:
        rc, err = run_cli(args(logs, tmp_path / "out", "--effects", "leak", "--fast"), capsys)
    finally:
        os.umask(old)
    assert rc == 0, err
    assert stat.S_IMODE(os.stat(tmp_path / "out").st_mode) == 0o755
    assert stat.S_IMODE(os.stat(tmp_path / "out" / "diagnosis.json").st_mode) == 0o644


@pytest.mark.parametrize("kind", ["foreign_folder", "file", "under_a_file", "unwritable"])
def test_out_is_checked_before_the_diagnosis_and_nothing_foreign_deleted(logs, tmp_path, capsys, monkeypatch,
                                                                        kind):
    """Issue 13: a folder holding other files is refused (never deleted), an
    existing file or an unwritable place is an error, all before any work."""
    out = tmp_path / "out"
    if kind == "foreign_folder":
        out.mkdir()
        (out / "notes.txt").write_text("mine")
        (out / "diagnosis.json").write_text("{}")
    elif kind == "file":
        out.write_text("a file")
    elif kind == "under_a_file":
        (tmp_path / "plain").write_text("x")
        out = tmp_path / "plain" / "out"
    else:
        locked = tmp_path / "locked"
        locked.mkdir()
        out = locked / "out"
        real_mkdtemp = cli.tempfile.mkdtemp

        def refuse(*a, **kw):   # as a read-only folder would (tests may run as root)
            if kw.get("dir") == str(locked):
                raise PermissionError(13, "Permission denied")
            return real_mkdtemp(*a, **kw)
        monkeypatch.setattr(cli.tempfile, "mkdtemp", refuse)
    from leveler.diagnose import pipeline
    monkeypatch.setattr(pipeline, "diagnose", lambda *a, **kw: pytest.fail("diagnosis ran before --out was checked"))
    rc, err = run_cli(args(logs, out, "--effects", "leak", "--fast"), capsys)
    assert rc == 2 and "--out" in err and "Traceback" not in err, err
    if kind == "foreign_folder":
        assert (out / "notes.txt").read_text() == "mine" and (out / "diagnosis.json").read_text() == "{}"
        assert "notes.txt" in err
    if kind == "file":
        assert out.read_text() == "a file"


def test_noise_only_answers_none(tmp_path, capsys):
    logs = make_logs(str(tmp_path), None, None, seed=3)
    rc, err = run_cli(args(logs, tmp_path / "out", "--effects", "leak,sensor_lag", "--fast"), capsys)
    assert rc == 0, err
    d = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert d["effect"] == "none" and d["effects"] == []
    assert not any(p["kept"] for p in d["pairs"])


def test_two_effects_at_once_are_both_named(tmp_path, capsys):
    """Truth: a leak and a lagging, offset pressure reading at once. The pair is
    fitted on top of the leader and kept; the report names both."""
    logs = make_logs(str(tmp_path), "leak+sensor_lag",
                     {"leak_area_m2": 1e-7, "tau_pressure_s": 1.0, "p_offset_pa": 8000.0}, seed=5)
    rc, err = run_cli(args(logs, tmp_path / "out", "--effects", "leak,sensor_lag,thermal", "--fast"), capsys)
    assert rc == 0, err
    d = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert sorted(d["effects"]) == ["leak", "sensor_lag"]
    kept = [p for p in d["pairs"] if p["kept"]]
    assert len(kept) == 1 and kept[0]["effects"] == d["effects"]
    assert kept[0]["closes_pct_of_leader_gap"] >= 30.0 and kept[0]["delta_bic"] < 0.0
    assert abs(d["shrink_pct"] - kept[0]["shrink_pct"]) < 1.0   # before/after is the pair's (every sample)
    assert "Two effects at once" in (tmp_path / "out" / "report.html").read_text()


def test_ranked_second_explains_what_the_leader_leaves(tmp_path, capsys):
    """Truth: a lagging, offset pressure reading and a weak leak. The stand-in's
    `area` offset raises the pressure a load needs as the reading's offset does:
    alone it ranks second, a look-alike of the leader that explains nothing the
    leader leaves. The ranked second effect must be the leak, the truth's second."""
    logs = make_logs(str(tmp_path), "sensor_lag+leak",
                     {"leak_area_m2": 2e-8, "tau_pressure_s": 1.0, "p_offset_pa": 8000.0}, seed=5)
    rc, err = run_cli(args(logs, tmp_path / "out", "--effects", "leak,sensor_lag,area", "--fast"), capsys)
    assert rc == 0, err
    d = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert d["effect"] == "sensor_lag"
    assert d["runner_up"] == "area"                 # the single look-alike of the leader
    assert d["second"]["effect"] == "leak" and d["ranked_combination"] == ["sensor_lag", "leak"]
    by = {p["effect"]: p for p in d["pairs"]}
    # the leak pair closes most of what the leader leaves; the look-alike's pair almost none of it
    assert by["sensor_lag+leak"]["closes_pct_of_leader_gap"] >= 50.0
    assert by["sensor_lag+area"]["closes_pct_of_leader_gap"] < 10.0
    assert "Ranked second" in (tmp_path / "out" / "report.html").read_text()


def test_the_calibrated_line_says_what_a_set_aside_calibration_would_have_moved():
    # misset seed 13, the pipe +30 % rig: the calibration (n -1.5 %) set aside for line_delay, alike
    rival = {"effect": "line_delay", "moved": ["polytropic_exponent"], "effect_gap": 0.381, "calibration_gap": 0.382}
    params = [{"name": "polytropic_exponent", "change_pct": -1.5, "moved": False}]
    result = {"experiment": {"between": ["line_delay", "calibration"]}}
    line = cli._calibrated_line({"parameters": params, "rival": rival, "alike": []}, result)
    assert line == ("not kept; polytropic_exponent would explain the held-out runs as well as line_delay "
                    "(experiment.csv tells them apart)")
    # kept: the values moved, the effect beside them
    params[0]["moved"] = True
    line = cli._calibrated_line({"parameters": params, "rival": rival, "alike": []}, result)
    assert line.startswith("polytropic_exponent -1.5%; line_delay alone would explain")
    assert cli._calibrated_line({"parameters": [dict(params[0], moved=False)]}, {}) == "no parameter moved"
