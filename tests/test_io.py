"""Output files (exo_ctrl._io): the up-front check, whole writes, special files, the umask."""

from __future__ import annotations

import os
import stat
import threading
from pathlib import Path

import pytest

from exo_ctrl._io import atomic_write, check_output, is_special, output_problem
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter, OutputError

ALLOWED = "a writable file in an existing directory"


@pytest.fixture
def umask():
    """Set the umask for one test (restored after it)."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


def read_fifo(path: Path) -> tuple[threading.Thread, list[bytes]]:
    """Start a thread that reads the FIFO at ``path`` to its end."""
    got: list[bytes] = []

    def reader() -> None:
        with open(path, "rb") as handle:
            got.append(handle.read())

    thread = threading.Thread(target=reader, daemon=True)
    thread.start()
    return thread, got


def test_check_output_refuses_a_missing_directory_and_creates_none(tmp_path: Path) -> None:
    path = tmp_path / "missing" / "deeper" / "s.json"
    with pytest.raises(InvalidParameter) as info:
        check_output(path, "--summary")
    assert str(info.value) == (
        f"--summary must be {ALLOWED}; got '{path}' "
        f"(directory {tmp_path / 'missing' / 'deeper'} does not exist)"
    )
    assert info.value.name == "--summary" and info.value.value == str(path)
    assert list(tmp_path.iterdir()) == []


def test_check_output_refuses_directories_and_files_as_directories(tmp_path: Path) -> None:
    with pytest.raises(InvalidParameter, match=rf"got '{tmp_path}' \({tmp_path} is a directory\)"):
        check_output(tmp_path, "--out")
    plain = tmp_path / "plain"
    plain.write_text("x")
    assert output_problem(plain / "s.json") == f"{plain} is not a directory"
    assert output_problem("") == "the path is empty"
    assert check_output(tmp_path / "new.csv", "--csv") == tmp_path / "new.csv"
    assert check_output(plain, "--csv") == plain  # an existing file is replaced


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores permissions")
def test_check_output_refuses_read_only_places(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    assert output_problem(locked / "x.csv") == f"permission denied on {locked}"
    frozen = tmp_path / "frozen.csv"
    frozen.write_text("x")
    frozen.chmod(0o400)
    assert output_problem(frozen) == f"permission denied on {frozen}"


def test_special_files_pass_the_check(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert is_special(fifo) and output_problem(fifo) is None
    assert not is_special(tmp_path / "new") and not is_special(tmp_path / "new" / "x")
    if Path("/dev/null").exists():
        assert is_special("/dev/null") and output_problem("/dev/null") is None


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_new_files_honour_the_umask(tmp_path: Path, umask, mask: int, mode: int) -> None:
    umask(mask)
    for name, how in (("a.csv", "w"), ("b.parquet", "wb")):
        with atomic_write(tmp_path / name, how) as handle:
            handle.write("x" if how == "w" else b"x")
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == mode, name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.parquet"]


def test_a_replaced_file_keeps_its_mode(tmp_path: Path, umask) -> None:
    umask(0o077)
    path = tmp_path / "old.json"
    path.write_text("old")
    path.chmod(0o640)
    with atomic_write(path) as handle:
        handle.write("new")
    assert path.read_text() == "new"
    assert stat.S_IMODE(path.stat().st_mode) == 0o640


def test_a_failure_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    path.write_text("previous\n")
    with pytest.raises(ZeroDivisionError), atomic_write(path) as handle:
        handle.write("half")
        _ = 1 / 0
    assert path.read_text() == "previous\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_errors_name_the_users_path_not_the_temporary(tmp_path: Path) -> None:
    path = tmp_path / "missing" / "bad.csv"
    with pytest.raises(OutputError) as info, atomic_write(path) as handle:
        handle.write("x")
    assert str(info.value) == f"cannot write {path}: No such file or directory"
    assert ".tmp" not in str(info.value) and isinstance(info.value, ExoCtrlError)
    assert isinstance(info.value, OSError) and info.value.path == str(path)
    assert not (tmp_path / "missing").exists()


def test_text_is_utf8_whatever_the_locale(tmp_path: Path) -> None:
    path = tmp_path / "report.txt"
    with atomic_write(path) as handle:
        handle.write("peak torque [N·m]: 115 — β = 0.5\n")
    assert path.read_bytes().decode("utf-8") == "peak torque [N·m]: 115 — β = 0.5\n"


def test_a_fifo_is_written_directly_and_stays_a_fifo(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    thread, got = read_fifo(fifo)
    with atomic_write(fifo) as handle:
        handle.write("t,x\n" * 10_000)
    thread.join(10)
    assert got == [b"t,x\n" * 10_000]
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["fifo"]


def test_a_symbolic_link_is_written_through_and_stays_a_link(tmp_path: Path) -> None:
    real = tmp_path / "real.csv"
    real.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    with atomic_write(link) as handle:
        handle.write("new")
    assert link.is_symlink() and real.read_text() == "new"


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_a_full_device_is_an_error_and_stays_a_device() -> None:
    with pytest.raises(OutputError) as info, atomic_write("/dev/full") as handle:
        handle.write("x" * 100)
    assert str(info.value) == "cannot write /dev/full: No space left on device"
    assert stat.S_ISCHR(os.lstat("/dev/full").st_mode)
