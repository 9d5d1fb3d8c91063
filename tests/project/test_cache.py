"""The compile cache (``drivemap.cache``, ``compiler.compile_cached``): reused only for the same bytes,
path, checks and drivemap; a corrupt or foreign entry is ignored and rebuilt; never a source of truth."""

from __future__ import annotations

import concurrent.futures
import contextlib
import io
import multiprocessing
import os
import shutil
import warnings
from pathlib import Path

import pytest

from drivemap import cache, compiler
from drivemap.build import build_checks
from drivemap.cli import main
from drivemap.compiler import compile_cached, compile_map

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("DRIVEMAP_CACHE_DIR", str(folder))
    monkeypatch.delenv("DRIVEMAP_NO_CACHE", raising=False)
    monkeypatch.chdir(tmp_path)
    return folder


@pytest.fixture
def no_compile(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Counts the compiles that really ran (the pipeline after the cache)."""
    ran: list[str] = []
    real = compiler.compile_document

    def counting(doc, exporters=None):  # type: ignore[no-untyped-def]
        ran.append(doc.path)
        return real(doc, exporters)

    monkeypatch.setattr(compiler, "compile_document", counting)
    return ran


def _map(tmp_path: Path, name: str = "vfd1000") -> Path:
    target = tmp_path / f"{name}.yaml"
    shutil.copy(ROOT / "maps" / f"{name}.yaml", target)
    return target


def _entries(folder: Path) -> list[Path]:
    return sorted(folder.glob("model-*.pickle"))


def test_second_compile_comes_from_the_cache_and_equals_a_fresh_one(store: Path, no_compile: list[str]) -> None:
    path = _map(store.parent)
    first = compile_cached(path.name)
    assert no_compile == ["vfd1000.yaml"] and len(_entries(store)) == 1
    second = compile_cached(path.name)
    assert no_compile == ["vfd1000.yaml"]  # nothing compiled again
    assert second == first == compile_map(path.name)
    assert second.path == "vfd1000.yaml"
    compile_cached(path.name, build_checks())  # other checks (build's python and docs exporters): another entry
    assert len(no_compile) == 3 and len(_entries(store)) == 2


def test_an_edited_map_is_compiled_again(store: Path, no_compile: list[str]) -> None:
    path = _map(store.parent)
    compile_cached(path.name)
    path.write_text(path.read_text(encoding="utf-8").replace("baudrates: [1200, 2400,", "baudrates: [2400,", 1),
                    encoding="utf-8")
    model = compile_cached(path.name)
    assert len(no_compile) == 2
    assert model.protocol.ports[0].baudrates[0] == 2400


def test_an_edited_base_map_is_compiled_again(store: Path, no_compile: list[str]) -> None:
    base = _map(store.parent)
    child = store.parent / "child.yaml"
    child.write_text("drivemap: 2\nextends: vfd1000\ndevice: {model: child, title: Child}\n", encoding="utf-8")
    old = os.stat(base).st_mtime - 10  # the cache stores no model whose base changed while it was read
    os.utime(base, (old, old))
    assert compile_cached("child.yaml").protocol.ports[0].baudrates[0] == 1200
    assert compile_cached("child.yaml").protocol.ports[0].baudrates[0] == 1200
    assert no_compile == ["child.yaml"]
    base.write_text(base.read_text(encoding="utf-8").replace("baudrates: [1200, 2400,", "baudrates: [2400,", 1),
                    encoding="utf-8")
    assert compile_cached("child.yaml").protocol.ports[0].baudrates[0] == 2400
    assert no_compile == ["child.yaml", "child.yaml"]


def test_the_path_a_map_is_shown_under_is_part_of_the_key(store: Path, no_compile: list[str]) -> None:
    path = _map(store.parent)
    assert compile_cached(path.name).path == "vfd1000.yaml"
    (store.parent / "sub").mkdir()
    os.chdir(store.parent / "sub")
    assert compile_cached(path).path == str(path)  # its messages point at the file as seen from here
    assert len(no_compile) == 2


@pytest.mark.parametrize("damage", ["garbage", "truncated", "foreign version", "other key", "not a model"])
def test_a_corrupt_or_foreign_entry_is_ignored_and_rebuilt(store: Path, no_compile: list[str], damage: str) -> None:
    path = _map(store.parent)
    model = compile_cached(path.name)
    [entry] = _entries(store)
    data = entry.read_bytes()
    header, _, body = data.partition(b"\n")
    if damage == "garbage":
        entry.write_bytes(b"\x00\xff not a pickle at all")
    elif damage == "truncated":
        entry.write_bytes(data[: len(data) // 2])
    elif damage == "foreign version":
        entry.write_bytes(header.replace(f" {cache.__version__} ".encode(), b" 0.0.1 ") + b"\n" + body)
    elif damage == "other key":
        entry.write_bytes(header[:-8] + b"00000000\n" + body)
    else:
        import pickle

        entry.write_bytes(header + b"\n" + pickle.dumps(((), "a model?", []), protocol=pickle.HIGHEST_PROTOCOL))
    assert compile_cached(path.name) == model
    assert len(no_compile) == 2  # ignored: compiled again ...
    assert entry.read_bytes() == data  # ... and the entry rebuilt
    compile_cached(path.name)
    assert len(no_compile) == 2


def test_never_trusted_across_versions(store: Path, no_compile: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path = _map(store.parent)
    compile_cached(path.name)
    monkeypatch.setattr(cache, "__version__", "99.0")
    cache.code_fingerprint.cache_clear()
    try:
        compile_cached(path.name)
        assert len(no_compile) == 2 and len(_entries(store)) == 2
        assert any("-99.0-" in p.name for p in _entries(store))
    finally:
        cache.code_fingerprint.cache_clear()


def test_an_edited_drivemap_source_makes_every_entry_stale(store: Path) -> None:
    before = cache.code_fingerprint()
    source = Path(cache.__file__)
    st = source.stat()
    try:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns + 1000))
        cache.code_fingerprint.cache_clear()
        assert cache.code_fingerprint() != before
    finally:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns))
        cache.code_fingerprint.cache_clear()
    assert cache.code_fingerprint() == before


def test_a_folder_others_may_write_is_not_used(store: Path, no_compile: list[str]) -> None:
    path = _map(store.parent)
    store.mkdir(mode=0o700)
    os.chmod(store, 0o777)
    compile_cached(path.name)
    compile_cached(path.name)
    assert len(no_compile) == 2 and _entries(store) == []
    os.chmod(store, 0o700)
    compile_cached(path.name)
    compile_cached(path.name)
    assert len(no_compile) == 3 and len(_entries(store)) == 1


def test_new_folder_is_private(store: Path) -> None:
    compile_cached(_map(store.parent).name)
    assert store.stat().st_mode & 0o777 == 0o700


def test_warnings_of_a_cached_compile_are_given_again(store: Path, no_compile: list[str],
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    path = _map(store.parent)
    from drivemap.frontend import checks

    real = checks.check

    def warning_check(doc):  # type: ignore[no-untyped-def]
        warnings.warn("vfd1000.yaml: a register is still open for review", UserWarning, stacklevel=1)
        return real(doc)

    monkeypatch.setattr(checks, "check", warning_check)
    with pytest.warns(UserWarning, match="open for review"):
        compile_cached(path.name)
    monkeypatch.setattr(checks, "check", real)
    with pytest.warns(UserWarning, match="open for review"):
        compile_cached(path.name)
    assert len(no_compile) == 1


def test_a_map_with_errors_is_not_cached(store: Path) -> None:
    path = _map(store.parent)
    path.write_text(path.read_text(encoding="utf-8").replace("modes: [rtu]", "modes: [carrier-pigeon]", 1),
                    encoding="utf-8")
    for _ in range(2):
        with pytest.raises(compiler.CompileError):
            compile_cached(path.name)
    assert _entries(store) == []


def test_no_cache_and_the_environment_switch(store: Path, no_compile: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path = _map(store.parent)
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["validate", "--no-cache", path.name]) == 0
    assert not store.exists()
    monkeypatch.setenv("DRIVEMAP_NO_CACHE", "1")
    compile_cached(path.name)
    assert not store.exists() and len(no_compile) == 2
    monkeypatch.delenv("DRIVEMAP_NO_CACHE")
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["validate", path.name]) == 0
        assert main(["validate", path.name]) == 0
    assert len(no_compile) == 3 and len(_entries(store)) == 1


def test_xdg_cache_home(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv("DRIVEMAP_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "drivemap"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert cache.cache_dir() == tmp_path / ".cache" / "drivemap"


def _compile_in_child(name: str) -> str:
    return compile_cached(name).name


def test_concurrent_compiles_share_one_whole_entry(store: Path) -> None:
    """Processes that compile the same map at once each get the model; one whole entry remains."""
    path = _map(store.parent)
    context = multiprocessing.get_context("fork")
    with concurrent.futures.ProcessPoolExecutor(4, mp_context=context) as pool:
        names = list(pool.map(_compile_in_child, [path.name] * 12))
    assert names == ["vfd1000"] * 12
    [entry] = _entries(store)
    assert not [p for p in store.iterdir() if p.name.startswith(".tmp-")]
    assert cache.load("model", entry.stem.split("-", 2)[2]) is not None
