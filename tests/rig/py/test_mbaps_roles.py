"""Issue 23, item 3: write rights over TLS come from the client certificate's
Modbus/TCP Security role (extension OID 1.3.6.1.4.1.50316.802.1, a
UTF8String), checked by leveler-mbaps, never from a source address.

A plant CA issues certificates with the roles Operator and ReadWrite (both in
[mbaps] write_roles), ReadOnly, none, and an Operator certificate that is then
revoked (the CRL in [mbaps] crl). leveler-mbaps reads the roles; the rig
lets only its [supervision] write_socket (a Unix socket, mode 0660) write,
so a plain TCP client, from 127.0.0.1 or 127.0.0.2 alike, reads only."""

import os
import socket
import ssl
import stat
import struct
import subprocess
import time

import pytest

import rigproc as rp
from test_stunnel_tls import make_ca, make_cert, revoke_and_publish_crl

ROLE_OID = "1.3.6.1.4.1.50316.802.1"
CLIENT_EXT = "extendedKeyUsage=clientAuth\n"
MBAPS = os.environ.get("LEVELER_MBAPS", "")


@pytest.fixture(scope="module")
def pki(tmp_path_factory):
    d = tmp_path_factory.mktemp("pki")
    make_ca(d, "ca")
    make_cert(d, "server", "ca", "subjectAltName=IP:127.0.0.1\nextendedKeyUsage=serverAuth\n")
    for name, role in (("operator", "Operator"), ("readwrite", "ReadWrite"), ("readonly", "ReadOnly"),
                       ("revoked", "Operator")):
        make_cert(d, name, "ca", CLIENT_EXT + f"{ROLE_OID}=ASN1:UTF8String:{role}\n")
    make_cert(d, "norole", "ca", CLIENT_EXT)
    revoke_and_publish_crl(d, "revoked")
    return d


@pytest.fixture
def mbaps(tmp_path, plant, pki):
    sock = tmp_path / "supervision.sock"
    port_file = tmp_path / "mbaps.port"
    rig = rp.Rig(tmp_path, plant, overrides={
        "supervision": {"write_socket": sock},
        "mbaps": {"address": "127.0.0.1", "port": 0, "port_file": port_file, "cert": pki / "server.pem",
                  "key": pki / "server.key", "ca": pki / "ca.pem", "crl": pki / "crl.pem",
                  "write_roles": "Operator, ReadWrite"}}).start()
    out = open(tmp_path / "mbaps.out", "w")
    proc = subprocess.Popen([MBAPS, "--config", str(rig.config_path)], stdout=out, stderr=subprocess.STDOUT)
    try:
        port = rp.read_port(port_file, proc, output=tmp_path / "mbaps.out")
        yield rig, port, sock
    finally:
        rp.stop_process(proc)
        out.close()
        rig.stop()
        print((tmp_path / "mbaps.out").read_text())


def tls_socket(pki, port, cert):
    ctx = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=str(pki / "ca.pem"))
    ctx.check_hostname = False
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    if cert:
        ctx.load_cert_chain(str(pki / f"{cert}.pem"), str(pki / f"{cert}.key"))
    raw = socket.create_connection(("127.0.0.1", port), timeout=3)
    return ctx.wrap_socket(raw)


def transact(s, tid, pdu):
    """One request, its reply's PDU (None if the connection ends)."""
    s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu)
    buf = b""
    try:
        while len(buf) < 7 or len(buf) < 6 + struct.unpack(">H", buf[4:6])[0]:
            chunk = s.recv(300)
            if not chunk:
                return None
            buf += chunk
    except (OSError, ssl.SSLError):
        return None
    assert struct.unpack(">H", buf[:2])[0] == tid
    return buf[7:]


def read_mode(s, tid):
    pdu = transact(s, tid, struct.pack(">BHH", 3, rp.HR_MODE, 1))
    assert pdu is not None and pdu[0] == 3, pdu
    return struct.unpack(">H", pdu[2:4])[0]


def write_mode(s, tid, mode):
    """The reply's function code: 6 (written) or 0x86 (exception), with its code."""
    pdu = transact(s, tid, struct.pack(">BHH", 6, rp.HR_MODE, mode))
    assert pdu is not None
    return pdu[0], (pdu[1] if pdu[0] & 0x80 else None)


@pytest.mark.parametrize("cert, writes", [("operator", True), ("readwrite", True), ("readonly", False),
                                          ("norole", False)])
def test_role_decides_writes(mbaps, pki, cert, writes):
    rig, port, _ = mbaps
    with tls_socket(pki, port, cert) as s:
        before = read_mode(s, 1)
        other = rp.MODE_MANUAL if before != rp.MODE_MANUAL else 1
        if writes:
            assert write_mode(s, 2, other) == (6, None)
            assert read_mode(s, 3) == other
            print(f"{cert}: mode {before} -> {other} written through TLS")
            return
        assert write_mode(s, 2, other) == (0x86, 1)
        # FC 16 and 05 too, and nothing changed
        assert transact(s, 3, struct.pack(">BHHBH", 16, rp.HR_MODE, 1, 2, other))[:2] == bytes([0x90, 1])
        assert transact(s, 4, struct.pack(">BHH", 5, rp.COIL_CLEAR_FAULTS, 0xFF00))[:2] == bytes([0x85, 1])
        assert read_mode(s, 5) == before
    print(f"{cert}: reads, every write refused with exception 01, mode unchanged")


@pytest.mark.parametrize("cert", [None, "revoked"])
def test_no_or_revoked_certificate_gets_no_connection(mbaps, pki, cert):
    rig, port, _ = mbaps
    try:
        with tls_socket(pki, port, cert) as s:
            got = transact(s, 1, struct.pack(">BHH", 6, rp.HR_MODE, rp.MODE_MANUAL))
    except (ssl.SSLError, OSError) as e:
        got = None
        print(f"certificate {cert}: refused ({type(e).__name__}: {e})")
    assert got is None
    c = rig.client()
    assert c.read_holding_registers(rp.HR_MODE, count=1).registers[0] != rp.MODE_MANUAL
    c.close()


@pytest.mark.parametrize("source", ["127.0.0.1", "127.0.0.2"])
def test_plain_tcp_client_cannot_write_whatever_its_address(mbaps, source):
    rig, port, sock = mbaps
    s = socket.create_connection(("127.0.0.1", rig.port), timeout=3, source_address=(source, 0))
    assert write_mode(s, 1, rp.MODE_MANUAL) == (0x86, 1)
    s.close()
    assert stat.S_IMODE(os.stat(sock).st_mode) == 0o660, "the write socket: owner and group only"
