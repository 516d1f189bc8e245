"""Item 9 of issue 13, item 3 of issue 23: Modbus/TCP Security in front of
the supervision port. The shipped stunnel config
(boards/linux-rig/stunnel-modbus-security.conf) runs with test certificates,
its CRL and loopback ports; pymodbus's TLS client (MBAP over TLS, as the
specification says) with a certificate from the plant CA reads through it;
without a certificate, with one from another CA or with a revoked one,
nothing gets through. stunnel cannot see a certificate's role, so with the
rig's write_socket set nothing that comes over TCP writes (roles:
test_mbaps_roles.py); a plain client reads."""

import socket
import ssl
import subprocess
import time
from pathlib import Path

import pytest

import rigproc as rp
from pymodbus.client import ModbusTlsClient

SHIPPED = Path(__file__).resolve().parents[3] / "boards" / "linux-rig" / "stunnel-modbus-security.conf"


def openssl(*args, cwd):
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=30)


def make_cert(d, name, ca, ext):
    (d / f"{name}.ext").write_text(ext)
    openssl("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", f"{name}.key",
            "-out", f"{name}.csr", "-subj", f"/CN={name}", cwd=d)
    openssl("x509", "-req", "-in", f"{name}.csr", "-CA", f"{ca}.pem", "-CAkey", f"{ca}.key", "-CAcreateserial",
            "-out", f"{name}.pem", "-days", "2", "-extfile", f"{name}.ext", cwd=d)


def make_ca(d, name):
    openssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout",
            f"{name}.key", "-out", f"{name}.pem", "-days", "2", "-subj", f"/CN={name}", cwd=d)


def revoke_and_publish_crl(pki, name):
    (pki / "index.txt").write_text("")
    (pki / "crlnumber").write_text("01\n")
    (pki / "ca.cnf").write_text("[ca]\ndefault_ca = plant\n[plant]\ndatabase = index.txt\ncrlnumber = crlnumber\n"
                                "default_md = sha256\ndefault_crl_days = 2\n")
    ca = ["-config", "ca.cnf", "-keyfile", "ca.key", "-cert", "ca.pem"]
    openssl("ca", *ca, "-revoke", f"{name}.pem", cwd=pki)
    openssl("ca", *ca, "-gencrl", "-out", "crl.pem", cwd=pki)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def tls(tmp_path, plant):
    pki = tmp_path / "pki"
    pki.mkdir()
    make_ca(pki, "ca")
    make_ca(pki, "rogue-ca")
    make_cert(pki, "server", "ca", "subjectAltName=IP:127.0.0.1\nextendedKeyUsage=serverAuth\n")
    make_cert(pki, "operator", "ca", "extendedKeyUsage=clientAuth\n")
    make_cert(pki, "intruder", "rogue-ca", "extendedKeyUsage=clientAuth\n")
    make_cert(pki, "revoked", "ca", "extendedKeyUsage=clientAuth\n")
    revoke_and_publish_crl(pki, "revoked")
    rig = rp.Rig(tmp_path, plant, overrides={"supervision": {"write_socket": tmp_path / "sv.sock"}}).start()
    port = free_port()
    conf = SHIPPED.read_text()
    for old, new in (("0.0.0.0:8802", f"127.0.0.1:{port}"), ("127.0.0.1:1502", f"127.0.0.1:{rig.port}"),
                     ("/etc/leveler/tls", str(pki)), ("pid =", f"pid =\noutput = {tmp_path}/stunnel.log")):
        assert old in conf
        conf = conf.replace(old, new)
    (tmp_path / "stunnel.conf").write_text(conf)
    proc = subprocess.Popen(["stunnel4", str(tmp_path / "stunnel.conf")], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)

    def listening():
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return True
        except OSError:
            return False
    try:
        assert rp.wait_until(listening, 10.0, 0.05), (tmp_path / "stunnel.log").read_text()
        yield pki, port, rig
    finally:
        proc.terminate()
        proc.wait(10)
        rig.stop()


def context(pki, cert=None):
    ctx = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=str(pki / "ca.pem"))
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    ctx.check_hostname = False   # pymodbus connects without a server name; the chain is still verified
    if cert:
        ctx.load_cert_chain(str(pki / f"{cert}.pem"), str(pki / f"{cert}.key"))
    return ctx


def test_certificate_holder_reads_through_tls_but_stunnel_gives_no_write_rights(tls):
    pki, port, rig = tls
    c = ModbusTlsClient("127.0.0.1", port=port, sslctx=context(pki, "operator"), timeout=3, retries=0)
    assert c.connect()
    up = c.read_input_registers(rp.IR_UPTIME_MS, count=2)
    assert not up.isError()
    r = c.write_register(rp.HR_MODE, rp.MODE_MANUAL)
    assert r.isError() and r.exception_code == 1
    assert c.read_holding_registers(rp.HR_MODE, count=1).registers[0] != rp.MODE_MANUAL
    c.close()
    print(f"TLS (client certificate): uptime {rp.u32(up.registers)} ms read, write refused (exception 01)")


@pytest.mark.parametrize("cert", [None, "intruder", "revoked"])
def test_no_or_foreign_certificate_gets_nothing_through(tls, cert):
    pki, port, rig = tls
    c = ModbusTlsClient("127.0.0.1", port=port, sslctx=context(pki, cert), timeout=2, retries=0)
    why = "connect refused"
    try:
        ok = c.connect()
        if ok:
            r = c.read_input_registers(rp.IR_UPTIME_MS, count=2)
            ok, why = not r.isError(), f"request failed: {r}"
    except Exception as e:   # handshake alert or reset: refused
        ok, why = False, f"{type(e).__name__}: {e}"
    finally:
        c.close()
    print(f"certificate {cert}: {why}")
    assert not ok
    assert "check_hostname" not in why


def test_plain_client_beside_the_proxy_may_read_but_not_write(tls):
    pki, port, rig = tls
    c = rp.connect(rig.port)
    assert not c.read_input_registers(rp.IR_UPTIME_MS, count=2).isError()
    r = c.write_register(rp.HR_MODE, rp.MODE_MANUAL)
    assert r.isError() and r.exception_code == 1
    c.close()
