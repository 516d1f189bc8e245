"""The leveler Python package as a user gets it (issue 22): the wheel built from
pyproject.toml by scikit-build-core with the project's CMake, installed into a
fresh virtual environment (runtime dependencies from the package registry), and
run from a folder outside the checkout with nothing of the checkout on its
paths: the console scripts answer --help and --version (the VERSION file), and
the C libraries the wheel carries simulate the thesis 900 lb rig as the
checkout's own build does (simulate_900lb.py in both)."""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
VERSION = os.environ["LEVELER_VERSION"]
SIMULATE = Path(__file__).with_name("simulate_900lb.py")
SCRIPTS = ["leveler-diagnose", "leveler-blindtest", "leveler-compare", "leveler-diagnose-bench", "leveler-report",
           "leveler-ctlbench-plot", "leveler-sweep"]   # leveler-sweep --version without the [sweep] extra (dask, pyarrow load when it runs)
COMPILED = ["leveler/_lib/libleveler_diag.so", "leveler/_lib/libleveler_truth.so",
            "leveler/_bin/leveler-sim"]
# the checkout's own build, from CTest; the installed package must find none of it
CHECKOUT_ENV = ("LEVELER_DIAG_LIB", "LEVELER_TRUTH_LIB", "LEVELER_SIM", "PYTHONPATH",
                "LEVELER_PYTHON", "PYTHONHOME", "VIRTUAL_ENV")


def run(argv, **kw):
    p = subprocess.run(argv, capture_output=True, text=True, timeout=600, **kw)
    assert p.returncode == 0, f"{argv}: exit {p.returncode}\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    return p


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    build_dir = os.environ["LEVELER_WHEEL_BUILD_DIR"]
    # no build isolation: scikit-build-core from .venv (scripts/requirements.txt), the system's cmake
    jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", "2")   # ninja would take every core
    run([sys.executable, "-m", "pip", "wheel", str(ROOT), "-w", str(out), "--no-deps", "--no-build-isolation",
         f"-Cbuild-dir={build_dir}"], env=dict(os.environ, CMAKE_BUILD_PARALLEL_LEVEL=jobs))
    wheels = list(out.glob("leveler-*.whl"))
    assert len(wheels) == 1, list(out.iterdir())
    print(f"\nwheel: {wheels[0].name}: {wheels[0].stat().st_size} bytes")
    return wheels[0]


@pytest.fixture(scope="module")
def installed(wheel):
    """A fresh venv with the wheel installed, in the system's temporary folder (outside
    the checkout); returns (venv bin, a folder to run in, the environment)."""
    top = Path(tempfile.mkdtemp(prefix="leveler-wheel-"))
    try:
        assert ROOT not in top.parents
        venv, outside = top / "venv", top / "work"
        outside.mkdir()
        run([sys.executable, "-m", "venv", str(venv)])
        run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(wheel)])
        env = {k: v for k, v in os.environ.items() if k not in CHECKOUT_ENV}
        env["MPLBACKEND"] = "Agg"
        yield venv / "bin", outside, env
    finally:
        shutil.rmtree(top, ignore_errors=True)


def test_wheel_holds_the_compiled_parts_and_the_data(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for path in COMPILED + ["leveler/_data/configs/thesis-900lb.ini", "leveler/_data/effects.json",
                            "leveler/_data/registers.json", "leveler/_data/blindtest/truth.json",
                            "leveler/_data/blindtest/truth2.json", "leveler/diagnose/templates/report.html.j2",
                            "leveler/paths.py"]:
        assert path in names, path
    configs = {Path(n).name for n in names if n.startswith("leveler/_data/configs/")}
    assert configs == {p.name for p in (ROOT / "host_sim" / "configs").glob("*.ini")}
    studies = {Path(n).name for n in names if n.startswith("leveler/_data/studies/")}
    assert studies == {p.name for p in (ROOT / "host_sim" / "studies").glob("*.toml")}
    assert not [n for n in names if "__pycache__" in n or n.startswith(("build/", "tests/"))]
    meta = zipfile.ZipFile(wheel).read(f"leveler-{VERSION}.dist-info/METADATA").decode()
    assert re.search(rf"^Version: {re.escape(VERSION)}$", meta, re.M)


def test_dependency_pins_are_the_requirements_pins():
    """pyproject.toml's runtime dependencies carry scripts/requirements.txt's pins (one tested set)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    deps = project["dependencies"] + [d for extra in project.get("optional-dependencies", {}).values() for d in extra]
    pins = dict(line.split("==") for line in (ROOT / "scripts" / "requirements.txt").read_text().splitlines()
                if "==" in line and not line.startswith("#"))
    for dep in deps:
        name, version = dep.split("==")
        assert pins.get(name) == version, f"pyproject.toml {dep}, scripts/requirements.txt {name}=={pins.get(name)}"


def test_console_scripts_help_and_version(installed):
    bin_dir, outside, env = installed
    h = run([str(bin_dir / "leveler-diagnose"), "--help"], cwd=outside, env=env)
    assert h.stdout.startswith("usage: leveler-diagnose") and "--config" in h.stdout
    v = run([str(bin_dir / "leveler-diagnose"), "--version"], cwd=outside, env=env)
    assert v.stdout == f"leveler-diagnose {VERSION}\n"
    for script in SCRIPTS:
        v = run([str(bin_dir / script), "--version"], cwd=outside, env=env)
        assert v.stdout.endswith(f" {VERSION}\n"), (script, v.stdout)


def test_installed_sweep_study_resolves_on_the_installed_configs(installed):
    """leveler-sweep's shipped study by name, its base configs resolved by the
    installed leveler-sim from the installed configs (no dask needed to expand it)."""
    bin_dir, outside, env = installed
    code = ("from leveler.sweep import study; s = study.load(study.find('accumulator')); "
            "print(len(s.points()), s.configs[0][1])")
    got = run([str(bin_dir / "python"), "-c", code], cwd=outside, env=env).stdout.split()
    assert got[0] == "100" and "/site-packages/leveler/_data/configs/thesis-900lb-tube.ini" in got[1], got


def test_installed_c_plant_simulates_as_the_checkout(installed):
    bin_dir, outside, env = installed
    got = json.loads(run([str(bin_dir / "python"), str(SIMULATE)], cwd=outside, env=env).stdout)
    site = Path(got["package"])
    assert got["checkout"] is None and Path(bin_dir).parent in site.parents, got["package"]
    for key in ("config_dir", "diag_lib", "truth_lib", "sim"):
        assert Path(got[key]).is_relative_to(site), (key, got[key])   # the package's own, not the checkout's
    want = json.loads(run([sys.executable, str(SIMULATE)], cwd=outside,
                          env=dict(os.environ, PYTHONPATH=str(ROOT / "scripts"))).stdout)
    assert want["checkout"] == str(ROOT) and want["diag_lib"] == os.environ["LEVELER_DIAG_LIB"]
    # physics: the rig starts inside the band, sinks below it under 240 lb more, and the
    # controller answers with the compressor while the load is on
    lo, hi = got["band_m"]
    assert lo <= got["height_start_m"] <= hi
    assert got["height_min_m"] < lo - 0.01
    assert got["compressor_on_loaded_ticks"] > 100
    # the wheel's build of the C plant is the checkout's: the same run to the micrometre
    for key in ("band_m", "compressor_on_ticks", "compressor_on_loaded_ticks"):
        assert got[key] == want[key], key
    for key in ("height_start_m", "height_min_m", "height_at_25s_m", "height_end_m", "replay_height_end_m"):
        assert got[key] == pytest.approx(want[key], abs=1e-6), key


def test_installed_engine_steps_the_plant_for_the_pil_harness(installed):
    """The PIL harness's plant is the installed engine's stepping API: 100 ticks
    from the built-in config's initial state, every actuator off after the first
    tick's [initial] ones, land on the checkout's engine's state to 1e-9 and one
    second later."""
    bin_dir, outside, env = installed
    code = ("import json; from leveler import engine; e = engine.Engine(None); e.step_open(); "
            "s0 = e.step_state(); [e.step([0, 0, 0, 0]) for _ in range(100)]; "
            "print(json.dumps([e.path, s0, e.step_state()]))")
    path, s0, s1 = json.loads(run([str(bin_dir / "python"), "-c", code], cwd=outside, env=env).stdout)
    assert Path(path).is_relative_to(Path(bin_dir).parent), path
    assert s1[0] == pytest.approx(s0[0] + 1.0, abs=1e-9)
    _, w0, w1 = json.loads(run([sys.executable, "-c", code], cwd=outside,
                               env=dict(os.environ, PYTHONPATH=str(ROOT / "scripts"))).stdout)
    for got, want in ((s0, w0), (s1, w1)):
        assert got[:4] == pytest.approx(want[:4], rel=1e-9), (got, want)


def test_installed_diagnosis_resolves_a_config_name(installed):
    """leveler-diagnose --config NAME on the thesis's published figures (the data the
    package carries): the name resolved in the package's configs, the C plant fitted,
    diagnosis.json and report.html written."""
    bin_dir, outside, env = installed
    data = run([str(bin_dir / "python"), "-c", "import leveler.diagnose, os; print(os.path.dirname(leveler.diagnose.__file__))"],
               cwd=outside, env=env).stdout.strip()
    out = outside / "diag"
    run([str(bin_dir / "leveler-diagnose"), "--config", "thesis-900lb", "--features",
         os.path.join(data, "data", "thesis-experiment.json"), "--out", str(out), "--fast", "--quiet"], cwd=outside, env=env)
    d = json.loads((out / "diagnosis.json").read_text())
    assert d["config"] == "thesis-900lb" and d["version"] == VERSION
    assert d["ranking"] and all(r["simulations"] > 0 for r in d["ranking"])
    assert (out / "report.html").stat().st_size > 10000
    bad = subprocess.run([str(bin_dir / "leveler-diagnose"), "--config", "no-such-rig", "--features",
                          os.path.join(data, "data", "thesis-experiment.json"), "--out", str(outside / "bad")],
                         cwd=outside, env=env, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "thesis-900lb" in bad.stderr, bad.stderr   # the known names are the package's
