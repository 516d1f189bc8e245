"""The rig host's Debian package, as a user gets it: built with CPack from the
test build, unpacked with dpkg-deb into a temporary root, and checked against
what a Debian system expects (the config a conffile, the unit enabled by the
maintainer scripts and not started, every path the unit names installed) and
against the installed program itself (leveler-rig --check on /etc/leveler/rig.ini)."""
import os
import re
import subprocess
from pathlib import Path

import pytest

CPACK = os.environ["LEVELER_CPACK"]
CONFIG = os.environ["LEVELER_CPACK_CONFIG"]
VERSION = os.environ["LEVELER_VERSION"]


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    out = tmp_path_factory.mktemp("cpack")
    p = subprocess.run([CPACK, "-G", "DEB", "--config", CONFIG, "-B", str(out)], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    debs = list(out.glob("*.deb"))
    assert len(debs) == 1, list(out.iterdir())
    root, control = out / "root", out / "control"
    subprocess.run(["dpkg-deb", "-x", str(debs[0]), str(root)], check=True)
    subprocess.run(["dpkg-deb", "-e", str(debs[0]), str(control)], check=True)
    return debs[0], root, control


def test_file_list(package):
    deb, root, _ = package
    assert deb.name == f"leveler-rig_{VERSION}_{subprocess.check_output(['dpkg', '--print-architecture'], text=True).strip()}.deb"
    for path in ["usr/bin/leveler-rig", "usr/bin/leveler-mbaps", "usr/bin/leveler-plant-server",
                 "usr/bin/leveler-schedule-run", "usr/bin/leveler-sim", "usr/lib/systemd/system/leveler-rig.service",
                 "usr/lib/udev/rules.d/60-leveler-gpio.rules", "etc/leveler/rig.ini",
                 "usr/share/doc/leveler/linux-rig/README.md", "usr/share/doc/leveler/registers.md", "usr/share/doc/leveler/leveler-tags.csv",
                 "usr/share/leveler/configs/thesis-900lb.ini"]:
        assert (root / path).is_file(), path
    assert os.access(root / "usr/bin/leveler-rig", os.X_OK)


def test_config_is_a_conffile_and_the_unit_is_enabled_not_started(package):
    _, _, control = package
    assert (control / "conffiles").read_text().split() == ["/etc/leveler/rig.ini"]
    postinst = (control / "postinst").read_text()
    assert "deb-systemd-helper enable 'leveler-rig.service'" in postinst
    assert "addgroup --system gpio" in postinst
    assert not re.search(r"\b(start|restart)\b", re.sub(r"#.*", "", postinst))   # enabled, not started
    for script in ("postinst", "prerm", "postrm"):
        assert os.access(control / script, os.X_OK), script
        subprocess.run(["sh", "-n", str(control / script)], check=True)   # valid shell
    fields = dict(line.split(": ", 1) for line in (control / "control").read_text().splitlines() if ": " in line)
    assert fields["Package"] == "leveler-rig" and fields["Version"] == VERSION


def test_installed_unit_names_installed_paths(package):
    _, root, _ = package
    unit = (root / "usr/lib/systemd/system/leveler-rig.service").read_text()
    execs = re.findall(r"^(?:ExecStartPre|ExecStart|ExecStopPost)=(\S+)", unit, re.M)
    assert execs == ["/usr/bin/leveler-rig"] * 3, execs
    assert "--config /etc/leveler/rig.ini" in unit
    doc = re.search(r"^Documentation=file://(\S+)", unit, re.M).group(1)
    assert (root / doc.lstrip("/")).is_file(), doc
    assert re.search(r"^SupplementaryGroups=.*\bgpio\b", unit, re.M)
    rules = (root / "usr/lib/udev/rules.d/60-leveler-gpio.rules").read_text()
    assert 'GROUP="gpio"' in rules


def test_installed_rig_checks_the_installed_config(package):
    _, root, _ = package
    cfg = root / "etc/leveler/rig.ini"
    p = subprocess.run([str(root / "usr/bin/leveler-rig"), "--check", "--config", str(cfg)], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == f"{cfg}: ok", p.stdout + p.stderr
    v = subprocess.run([str(root / "usr/bin/leveler-rig"), "--version"], capture_output=True, text=True)
    assert v.stdout.strip() == f"leveler-rig {VERSION}"
