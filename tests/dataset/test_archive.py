"""pack and fetch against a real HTTP server on 127.0.0.1, started by the test."""

import hashlib
import http.server
import io
import shutil
import tarfile
import threading
from pathlib import Path

import pytest

from simlidar.errors import DatasetError
from simlidar.release.archive import FetchError, fetch, pack
from simlidar.release.checksums import sha256_file


class _Handler(http.server.SimpleHTTPRequestHandler):
    release = threading.Event()  # set at teardown so a hanging request ends

    def log_message(self, *args):  # keep the test output clean
        pass

    def do_GET(self):
        if self.path.startswith("/truncated/"):
            body = (Path(self.directory) / self.path.split("/", 2)[2]).read_bytes()
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body[: len(body) // 2])  # then the connection closes
            self.close_connection = True
            return
        if self.path.startswith("/hang/"):
            self.release.wait(timeout=10)  # never answers within the client's timeout
            return
        super().do_GET()


@pytest.fixture
def server(tmp_path):
    """(base URL, served folder) of a server that stops when the test ends."""
    root = tmp_path / "www"
    root.mkdir()
    _Handler.release.clear()
    httpd = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), lambda *a: _Handler(*a, directory=str(root))
    )
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}", root
    _Handler.release.set()
    httpd.shutdown()
    httpd.server_close()
    thread.join(timeout=5)


@pytest.fixture
def packed(datasets, server):
    """The small dataset packed into the served folder: (archive, its sha256)."""
    archive, checksum = pack(datasets[0.1], server[1])
    return archive, checksum.read_text().split()[0]


def test_pack_is_reproducible_and_checksummed(datasets, tmp_path):
    a, sa = pack(datasets[0.1], tmp_path / "a")
    b, _ = pack(datasets[0.1], tmp_path / "b")
    assert a.name == f"{datasets[0.1].name}.tar.gz"
    assert a.read_bytes() == b.read_bytes()
    assert sa.read_text() == f"{sha256_file(a)}  {a.name}\n"
    with tarfile.open(a) as tar:
        names = tar.getnames()
    assert names[0] == datasets[0.1].name and f"{datasets[0.1].name}/train.h5" in names


def test_pack_refuses_a_damaged_dataset(datasets, tmp_path):
    copy = tmp_path / "d"
    shutil.copytree(datasets[0.1], copy)
    (copy / "preview.png").write_bytes(b"changed")
    with pytest.raises(DatasetError, match="preview.png: sha256 does not match"):
        pack(copy, tmp_path / "out")
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


def test_pack_refuses_an_out_inside_the_dataset(datasets, tmp_path):
    copy = tmp_path / "d"
    shutil.copytree(datasets[0.1], copy)
    for out in (copy, copy / "sub"):
        with pytest.raises(DatasetError, match="expected a folder outside the dataset"):
            pack(copy, out)
    assert sorted(p.name for p in copy.iterdir()) == sorted(p.name for p in datasets[0.1].iterdir())


def test_an_archive_made_with_dot_slash_members_installs(server, datasets, tmp_path):
    url, root = server
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:  # like `tar czf x.tar.gz -C d .`
        tar.add(datasets[0.1].parent, arcname=".", recursive=False)
        tar.add(datasets[0.1], arcname=f"./{datasets[0.1].name}")
    (root / "dot.tar.gz").write_bytes(buffer.getvalue())
    digest = hashlib.sha256(buffer.getvalue()).hexdigest()
    installed = fetch(f"{url}/dot.tar.gz", sha256=digest, out=tmp_path / "d", progress=False)
    assert installed.name == datasets[0.1].name


def test_a_sharded_dataset_packs_and_fetches_whole(server, sharded, tmp_path):
    from simlidar.data import load_split
    from simlidar.release.verify import verify

    url, root = server
    archive, _ = pack(sharded, root)
    installed = fetch(f"{url}/{archive.name}", out=tmp_path / "d", progress=False)
    names = sorted(p.name for p in installed.iterdir())
    assert names == sorted(p.name for p in sharded.iterdir())
    assert verify(installed) == []
    assert (load_split(installed, "train")[1] == load_split(sharded, "train")[1]).all()


def test_a_member_conflict_names_the_extract_step(server, datasets, tmp_path):
    url, root = server
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        tar.add(datasets[0.1], arcname="ds")
        info = tarfile.TarInfo("ds")  # a file where the folder is
        info.size = 1
        tar.addfile(info, io.BytesIO(b"x"))
    (root / "conflict.tar.gz").write_bytes(buffer.getvalue())
    digest = hashlib.sha256(buffer.getvalue()).hexdigest()
    with pytest.raises(FetchError, match="fetch failed at extract"):
        fetch(f"{url}/conflict.tar.gz", sha256=digest, out=tmp_path / "d", progress=False)


def test_fetch_a_good_archive(server, packed, tmp_path, datasets):
    url, _ = server
    out = tmp_path / "data"
    installed = fetch(f"{url}/{packed[0].name}", out=out, progress=False)  # sidecar .sha256
    assert installed == out / datasets[0.1].name
    assert (installed / "train.h5").read_bytes() == (datasets[0.1] / "train.h5").read_bytes()
    assert sorted(p.name for p in out.iterdir()) == [datasets[0.1].name]  # nothing else left
    with pytest.raises(FetchError, match="fetch failed at install: .* already exists"):
        fetch(f"{url}/{packed[0].name}", sha256=packed[1], out=out, progress=False)
    fetch(f"{url}/{packed[0].name}", sha256=packed[1], out=out, progress=False, force=True)


def _assert_nothing_left(out):
    assert not out.exists() or list(out.iterdir()) == []


def test_a_tampered_archive_fails_the_checksum(server, packed, tmp_path):
    url, root = server
    data = bytearray(packed[0].read_bytes())
    data[len(data) // 2] ^= 0x01
    (root / "tampered.tar.gz").write_bytes(bytes(data))
    out = tmp_path / "data"
    with pytest.raises(FetchError, match="fetch failed at checksum: sha256 .* does not match"):
        fetch(f"{url}/tampered.tar.gz", sha256=packed[1], out=out, progress=False)
    _assert_nothing_left(out)


def test_a_truncated_download_fails(server, packed, tmp_path):
    url, _ = server
    out = tmp_path / "data"
    with pytest.raises(FetchError, match="fetch failed at download"):
        fetch(f"{url}/truncated/{packed[0].name}", sha256=packed[1], out=out, progress=False)
    _assert_nothing_left(out)


def _evil_archive(root: Path, member: str, link: bool = False) -> tuple[str, str]:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        info = tarfile.TarInfo(member)
        if link:
            info.type, info.linkname = tarfile.SYMTYPE, "/etc/passwd"
            tar.addfile(info)
        else:
            info.size = 4
            tar.addfile(info, io.BytesIO(b"evil"))
    data = buffer.getvalue()
    name = f"evil{abs(hash(member))}.tar.gz"
    (root / name).write_bytes(data)
    return name, hashlib.sha256(data).hexdigest()


@pytest.mark.parametrize(
    "member, link, words",
    [
        ("../escaped.txt", False, "would land outside the target"),
        ("/tmp/absolute.txt", False, "would land outside the target"),
        ("d/link", True, "is a link or special file"),
    ],
)
def test_path_traversal_is_refused(server, tmp_path, member, link, words):
    url, root = server
    name, digest = _evil_archive(root, member, link)
    out = tmp_path / "data"
    with pytest.raises(FetchError, match=f"fetch failed at extract: .*{words}"):
        fetch(f"{url}/{name}", sha256=digest, out=out, progress=False)
    _assert_nothing_left(out)
    assert not (tmp_path / "escaped.txt").exists()


def test_an_archive_over_the_size_limit_is_refused(server, packed, tmp_path):
    url, _ = server
    with pytest.raises(FetchError, match="fetch failed at extract: .* more than the limit 1000"):
        fetch(
            f"{url}/{packed[0].name}",
            sha256=packed[1],
            out=tmp_path / "d",
            progress=False,
            max_bytes=1000,
        )


def test_a_404_is_named(server, tmp_path):
    url, _ = server
    with pytest.raises(FetchError, match="fetch failed at download: .*HTTP 404"):
        fetch(f"{url}/missing.tar.gz", sha256="0" * 64, out=tmp_path / "d", progress=False)


def test_a_missing_sidecar_checksum_is_named(server, packed, tmp_path):
    url, root = server
    (root / f"{packed[0].name}.sha256").unlink()
    with pytest.raises(FetchError, match="fetch failed at checksum: no --sha256 given"):
        fetch(f"{url}/{packed[0].name}", out=tmp_path / "d", progress=False)


def test_a_hanging_server_is_bounded_by_the_timeout(server, tmp_path):
    url, _ = server
    with pytest.raises(FetchError, match="fetch failed at download: .*no answer within 0.5 s"):
        fetch(
            f"{url}/hang/x.tar.gz", sha256="0" * 64, out=tmp_path / "d", timeout=0.5, progress=False
        )


def test_an_unreachable_host_is_named(tmp_path):
    with pytest.raises(FetchError, match="fetch failed at download: http://127.0.0.1:9/"):
        fetch(
            "http://127.0.0.1:9/x.tar.gz",
            sha256="0" * 64,
            out=tmp_path / "d",
            timeout=2,
            progress=False,
        )


def test_a_dataset_that_fails_verify_is_not_installed(server, datasets, tmp_path):
    url, root = server
    copy = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], copy)
    (copy / "notes.txt").write_text("unlisted")
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        tar.add(copy, arcname=copy.name)
    (root / "unverified.tar.gz").write_bytes(buffer.getvalue())
    digest = hashlib.sha256(buffer.getvalue()).hexdigest()
    out = tmp_path / "data"
    with pytest.raises(FetchError, match="fetch failed at verify: .*notes.txt: not listed"):
        fetch(f"{url}/unverified.tar.gz", sha256=digest, out=out, progress=False)
    _assert_nothing_left(out)
