"""``simlidar fetch`` bounds what it reads before reading it (issue 58, finding 1).

Attack list, each archive or server made here and served on 127.0.0.1:
- tar extension headers that declare more than anything could need: a GNU long name, a long
  link, a pax extended and a pax global header of 4 GiB (a 512-byte header, nothing after
  it) and a long name of 2**62 bytes in base-256; tarfile read each declared size into memory
  (a 74-byte archive declaring 1 GiB took 1 GiB; 4 GiB under the 2 GiB limit here: a
  MemoryError traceback). Run in a child process under ``ulimit -v``;
- a name of 5,000 characters (as a GNU long name and as a pax path), a folder level of 300;
- nine pax headers chained before one member, a GNU sparse member, a pax sparse map of
  1,000,000 entries (read without a bound), and a pax global header of 64 KiB of short
  records before 100 empty members (tarfile copies it into each: 1 GB for 10,000 members);
- a download without Content-Length past the cap, a Content-Length over the cap, a disk with
  too little free space before the download, one that fills while it runs, and too little
  room to unpack;
- SIGTERM and SIGINT while a server trickles the download: the work folder is removed.
"""

import gzip
import hashlib
import http.server
import io
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import threading
import time
from pathlib import Path

import pytest

from simlidar.atomic import Interrupted, Temporary, stopped_by_signals, uninterrupted
from simlidar.release.archive import FetchError, archive_limit, fetch
from simlidar.release.untar import MAX_HEADER_CHAIN, MAX_PAX_TOTAL, MIN_FREE_BYTES
from simlidar.resources import size_text

ROOT = Path(__file__).parents[2]


def _block(name: str, kind: bytes, size: int = 0) -> bytes:
    """One 512-byte tar header of type ``kind`` declaring ``size`` bytes of payload (octal,
    or base-256 past 8 GiB as GNU tar writes it), with a correct checksum."""
    info = tarfile.TarInfo(name)
    info.type = kind
    header = bytearray(info.tobuf(tarfile.USTAR_FORMAT)[:512])
    header[124:136] = b"%011o\0" % size if size < 8**11 else b"\x80" + size.to_bytes(11, "big")
    header[148:156] = b" " * 8
    header[148:156] = b"%06o\0 " % sum(header)
    return bytes(header)


def _padded(payload: bytes) -> bytes:
    return payload + bytes(-len(payload) % 512)


def _pax(records: dict[str, str], kind: bytes = tarfile.XHDTYPE) -> bytes:
    """A pax header of ``records`` with its payload."""
    text = b""
    for key, value in records.items():
        body = f" {key}={value}\n".encode()
        length = len(body) + 1  # a record's length counts its own digits
        while len(str(length)) + len(body) != length:
            length = len(str(length)) + len(body)
        text += str(length).encode() + body
    return _block("pax", kind, len(text)) + _padded(text)


def _served(root: Path, name: str, tar_bytes: bytes) -> tuple[str, str]:
    """``tar_bytes`` (with two end blocks added) gzipped into ``root/name``: (name, sha256)."""
    data = gzip.compress(tar_bytes + bytes(1024), mtime=0)
    (root / name).write_bytes(data)
    return name, hashlib.sha256(data).hexdigest()


def _file(name: str, data: bytes = b"") -> bytes:
    return _block(name, tarfile.REGTYPE, len(data)) + _padded(data)


def _refused(url: str, digest: str, out: Path, words: str, **options) -> str:
    """Fetch ``url`` and return the one-line FetchError, which must contain ``words``, with
    nothing left in ``out``."""
    with pytest.raises(FetchError) as refusal:
        fetch(url, sha256=digest, out=out, progress=False, **options)
    message = str(refusal.value)
    assert words in message and "\n" not in message, message
    assert not out.exists() or list(out.iterdir()) == []
    return message


HEADER_BOMBS = {
    "long-name": (
        _block("././@LongLink", tarfile.GNUTYPE_LONGNAME, 4 * 2**30),
        "a GNU long-name header of 4294967296 bytes; expected at most 4096",
    ),
    "long-link": (
        _block("././@LongLink", tarfile.GNUTYPE_LONGLINK, 4 * 2**30),
        "a GNU long-link header of 4294967296 bytes; expected at most 4096",
    ),
    "pax": (
        _block("pax", tarfile.XHDTYPE, 4 * 2**30),
        "a pax header of 4294967296 bytes; expected at most 65536",
    ),
    "pax-global": (
        _block("pax", tarfile.XGLTYPE, 4 * 2**30),
        "a pax global header of 4294967296 bytes; expected at most 65536",
    ),
    "base-256": (
        _block("././@LongLink", tarfile.GNUTYPE_LONGNAME, 2**62),
        f"a GNU long-name header of {2**62} bytes; expected at most 4096",
    ),
}


def test_header_bombs_are_refused_before_their_payload_is_read(server, tmp_path, limited_python):
    """In a child process under a 2 GiB address-space limit (the headers declare 4 GiB and
    more): fetch each, printing its one-line refusal; a MemoryError is a traceback."""
    url, root = server
    expected = []
    for kind, (header, words) in HEADER_BOMBS.items():
        name, digest = _served(root, f"{kind}.tar.gz", header)
        assert (root / name).stat().st_size < 200  # the archive holds nothing but the header
        expected.append((f"{url}/{name}", digest, words))
    script = (
        "import sys\n"
        "from simlidar.release.archive import FetchError, fetch\n"
        "for url, digest in zip(sys.argv[2::2], sys.argv[3::2]):\n"
        "    try:\n"
        "        fetch(url, sha256=digest, out=sys.argv[1], progress=False)\n"
        "    except FetchError as exc:\n"
        "        print(exc)\n"
    )
    out = tmp_path / "out"
    args = [a for url, digest, _ in expected for a in (url, digest)]
    result = limited_python(["-c", script, out, *args], 2 * 2**30, timeout=120)
    assert result.returncode == 0 and result.stderr == "", result.stderr[-2000:]
    lines = result.stdout.splitlines()
    assert lines == [f"fetch failed at extract: {words}" for _, _, words in expected]
    assert not out.exists()


def test_the_command_refuses_a_header_bomb_in_one_line(server, tmp_path, limited_python):
    url, root = server
    header, words = HEADER_BOMBS["long-name"]
    name, digest = _served(root, "bomb.tar.gz", header)
    out = tmp_path / "out"
    out.mkdir()
    command = ["-m", "simlidar.cli", "fetch", f"{url}/{name}", "--sha256", digest, "--out", out]
    result = limited_python(command, 2 * 2**30, timeout=120)
    assert result.returncode == 1, result.stderr[-2000:]
    assert result.stderr.splitlines()[-1] == f"Error: fetch failed at extract: {words}"
    assert "Traceback" not in result.stderr
    assert list(out.iterdir()) == []


def test_a_name_of_5000_characters_is_refused_in_a_short_line(server, tmp_path):
    url, root = server
    name = "d/" + "a" * 4998
    for format, words in [
        (tarfile.GNU_FORMAT, "a GNU long-name header of 5001 bytes; expected at most 4096"),
        (tarfile.PAX_FORMAT, "a name of 5000 bytes, a level of 4998; expected under 4096"),
    ]:
        buffer = io.BytesIO()
        with tarfile.open(fileobj=buffer, mode="w:gz", format=format) as tar:
            tar.addfile(tarfile.TarInfo(name), io.BytesIO(b""))
        served = f"long{format}.tar.gz"
        (root / served).write_bytes(buffer.getvalue())
        digest = hashlib.sha256(buffer.getvalue()).hexdigest()
        message = _refused(f"{url}/{served}", digest, tmp_path / "out", words)
        assert len(message) < 300, message  # the name is cut, not printed whole


def test_a_folder_level_longer_than_name_max_is_refused(server, tmp_path):
    url, root = server
    name, digest = _served(root, "level.tar.gz", _pax({"path": "d/" + "b" * 300}) + _file("x"))
    _refused(
        f"{url}/{name}", digest, tmp_path / "out", "a name of 302 bytes, a level of 300; expected"
    )


def test_a_chain_of_pax_headers_is_refused(server, tmp_path):
    url, root = server
    chain = b"".join(_pax({"comment": str(k)}) for k in range(MAX_HEADER_CHAIN + 1))
    name, digest = _served(root, "chain.tar.gz", chain + _file("d/x"))
    _refused(f"{url}/{name}", digest, tmp_path / "out", "more than 8 extension headers")


def test_sparse_members_are_refused(server, tmp_path):
    """A GNU sparse header, and a pax sparse map (format 1.0) announcing 1,000,000 entries:
    tarfile reads such a map from the member's data without a bound."""
    url, root = server
    name, digest = _served(root, "gnu-sparse.tar.gz", _block("d/x", tarfile.GNUTYPE_SPARSE))
    _refused(f"{url}/{name}", digest, tmp_path / "out", "a sparse file; expected only files")
    entries = 1_000_000
    sparse_map = f"{entries}\n".encode() + b"0\n1\n" * entries
    records = {"GNU.sparse.major": "1", "GNU.sparse.minor": "0", "GNU.sparse.name": "d/x"}
    records["GNU.sparse.realsize"] = str(entries)
    member = _pax(records) + _file("d/GNUSparseFile.0/x", sparse_map)
    name, digest = _served(root, "pax-sparse.tar.gz", member)
    _refused(f"{url}/{name}", digest, tmp_path / "out", "a sparse file; expected only files")


def test_pax_records_copied_into_each_member_are_bounded(server, tmp_path):
    """A pax global header of 64 KiB of short records before 100 empty members: tarfile
    copies its records into each member (with 10,000 members, 1 GB and 22 s)."""
    url, root = server
    records = {f"k{k:05d}": "" for k in range(5000)}
    members = b"".join(_file(f"d/{k:03d}") for k in range(100))
    name, digest = _served(root, "global.tar.gz", _pax(records, tarfile.XGLTYPE) + members)
    _refused(f"{url}/{name}", digest, tmp_path / "out", f"pax records of more than {MAX_PAX_TOTAL}")


def test_pax_records_as_writers_use_them_install(server, datasets, tmp_path):
    """A global comment (as ``git archive`` writes) and times to the nanosecond on every
    member (as GNU tar's pax format writes) stay far inside the bounds."""
    url, root = server
    folder = datasets[0.1]
    buffer = io.BytesIO()
    comment = {"comment": "0123456789abcdef0123456789abcdef01234567"}
    with tarfile.open(
        fileobj=buffer, mode="w:gz", format=tarfile.PAX_FORMAT, pax_headers=comment
    ) as tar:
        for path in [folder, *sorted(folder.iterdir())]:
            info = tar.gettarinfo(path, arcname=str(path.relative_to(folder.parent)))
            info.pax_headers = {"atime": "1700000000.123456789", "ctime": "1700000000.1"}
            tar.addfile(info, io.BytesIO(path.read_bytes()) if path.is_file() else None)
    served = f"{folder.name}.tar.gz"
    (root / served).write_bytes(buffer.getvalue())
    digest = hashlib.sha256(buffer.getvalue()).hexdigest()
    installed = fetch(f"{url}/{served}", sha256=digest, out=tmp_path / "out", progress=False)
    assert sorted(p.name for p in installed.iterdir()) == sorted(p.name for p in folder.iterdir())


# the most a _Sender sends before it closes the connection: past every bound tested here
# (archive_limit(1000) is 56 MB), yet a fetch that lost its bounds fails the test instead of
# filling the disk (the unbounded code wrote 80 GB in two minutes)
SENT_AT_MOST = 1 << 27


class _Sender(http.server.BaseHTTPRequestHandler):
    """``/endless/<name>``: zeros without a Content-Length; ``/declared/<name>``: a
    Content-Length of 10**12, then zeros; both until SENT_AT_MOST."""

    def log_message(self, *args):
        pass

    def do_GET(self):
        self.send_response(200)
        if self.path.startswith("/declared/"):
            self.send_header("Content-Length", str(10**12))
        self.end_headers()
        zeros = bytes(1 << 16)
        try:
            for _ in range(SENT_AT_MOST // len(zeros)):
                self.wfile.write(zeros)
        except OSError:  # the client gave up
            pass
        self.close_connection = True


@pytest.fixture
def sender():
    """The base URL of a :class:`_Sender` server on 127.0.0.1."""
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Sender)
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
    httpd.server_close()
    thread.join(timeout=5)


def test_a_download_without_a_length_stops_at_the_cap(sender, tmp_path):
    limit = archive_limit(1000)
    assert limit < SENT_AT_MOST // 2
    _refused(
        f"{sender}/endless/x.tar.gz",
        "0" * 64,
        tmp_path / "out",
        f"fetch failed at download: {sender}/endless/x.tar.gz: more than the limit of {limit} "
        "bytes received",
        max_bytes=1000,
    )


def test_a_length_over_the_cap_is_refused_before_reading(sender, tmp_path):
    _refused(
        f"{sender}/declared/x.tar.gz",
        "0" * 64,
        tmp_path / "out",
        f"/declared/x.tar.gz: the server announces {10**12} bytes, more than the limit "
        f"{archive_limit(2**30)}",
        max_bytes=2**30,
    )


def _disk(monkeypatch, free):
    """Make the disk report ``free()`` bytes free."""
    real = shutil.disk_usage

    def usage(path):
        return real(path)._replace(free=free())

    monkeypatch.setattr(shutil, "disk_usage", usage)


def test_a_download_too_large_for_the_disk_is_refused_before_it_starts(
    server, packed, tmp_path, monkeypatch
):
    url, _ = server
    _disk(monkeypatch, lambda: MIN_FREE_BYTES)
    size = size_text(packed[0].stat().st_size)
    message = _refused(
        f"{url}/{packed[0].name}",
        packed[1],
        tmp_path / "out",
        f"fetch failed at download: {url}/{packed[0].name}: a download of {size}, 64.0 MiB "
        "free in ",
    )
    assert message.endswith(
        "; expected room for it and 64.0 MiB to spare (free some space, or choose another --out)"
    )


def test_a_download_without_a_length_stops_while_the_disk_fills(sender, tmp_path, monkeypatch):
    """The disk has 80 MiB free before the download; what arrives takes from them."""
    out = tmp_path / "out"

    def free():
        arrived = sum(p.stat().st_size for p in out.glob(".*.fetch-*/archive.tar.gz"))
        return 80 * 2**20 - arrived

    _disk(monkeypatch, free)
    message = _refused(
        f"{sender}/endless/x.tar.gz",
        "0" * 64,
        out,
        " MiB received, no length given, ",
        max_bytes=2**30,
    )
    assert " MiB free in " in message and "expected room for it and 64.0 MiB" in message


def test_an_archive_too_large_to_unpack_is_refused_before_extracting(
    server, packed, tmp_path, monkeypatch
):
    url, _ = server
    checks = []

    def free():  # room for the download (the first check), none to unpack (the next)
        checks.append(1)
        return 2**40 if len(checks) == 1 else MIN_FREE_BYTES

    _disk(monkeypatch, free)
    _refused(
        f"{url}/{packed[0].name}",
        packed[1],
        tmp_path / "out",
        " KiB to unpack, 64.0 MiB free in ",
    )
    assert len(checks) == 2


@pytest.mark.parametrize("signal_number", [signal.SIGTERM, signal.SIGINT])
def test_a_fetch_stopped_by_a_signal_removes_its_work_folder(server, tmp_path, signal_number):
    url, _ = server
    out = tmp_path / "out"
    out.mkdir()
    source = f"{url}/trickle/x.tar.gz"  # a byte every 0.1 s, for ever
    command = [sys.executable, "-m", "simlidar.cli", "fetch", source, "--sha256", "0" * 64]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen(
        [*command, "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    deadline = time.monotonic() + 60
    while not list(out.glob(".x.fetch-*/archive.tar.gz")):  # the download has begun
        assert time.monotonic() < deadline and process.poll() is None, "fetch did not start"
        time.sleep(0.01)
    process.send_signal(signal_number)
    _, err = process.communicate(timeout=30)
    name = signal.Signals(signal_number).name
    lines = [line.rsplit("\r", 1)[-1] for line in err.decode().split("\n")]  # less the bar
    assert [line for line in lines if line.strip()] == [
        f"Error: fetch {source}: stopped by {name}; the files it was writing are removed"
    ], err
    assert process.returncode == 1
    assert list(out.iterdir()) == []


def test_signal_handlers_are_restored_after_fetch(server, packed, tmp_path):
    url, _ = server
    before = [signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)]
    fetch(f"{url}/{packed[0].name}", out=tmp_path / "out", progress=False)
    with pytest.raises(FetchError):
        fetch(f"{url}/missing.tar.gz", sha256="0" * 64, out=tmp_path / "o", progress=False)
    assert [signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)] == before


def test_the_download_bound_covers_a_packed_archive(packed):
    """pack's archive of a dataset is within archive_limit of its unpacked size."""
    with tarfile.open(packed[0]) as tar:
        unpacked = sum(m.size for m in tar.getmembers())
    assert packed[0].stat().st_size <= archive_limit(unpacked)


def test_a_signal_while_a_temporary_is_removed_waits_for_the_removal(tmp_path):
    """What fetch's cleanup relies on: a SIGTERM inside ``uninterrupted`` (here, at its start)
    is raised when the block ends, the temporary removed whole; a second one is ignored."""
    before = signal.getsignal(signal.SIGTERM)
    temporary = Temporary(tmp_path, "x", "fetch")
    (temporary.path / "archive.tar.gz").write_bytes(b"x")
    done = []
    with pytest.raises(Interrupted, match="^fetch x: stopped by SIGTERM; the files it was"):
        with stopped_by_signals("fetch x"):
            with uninterrupted():
                os.kill(os.getpid(), signal.SIGTERM)
                os.kill(os.getpid(), signal.SIGTERM)
                temporary.release()
                done.append("released")
    assert done == ["released"] and list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) == before
