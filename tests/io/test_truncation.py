"""Acceptance 3: a file cut in the middle gives a clear error; recover returns the messages before the cut."""

import argparse

import numpy as np
import pytest

from pasta.io import McapTruncatedError, RunLogger, RunReader
from pasta.io import replay


def _write(path, n=200):
    rng = np.random.default_rng(1)
    clouds = [rng.random((500, 3)).astype(np.float32) for _ in range(n)]
    with RunLogger(path, config_yaml="a: 1\n", metadata={"seed": "1"}, chunk_size=16 * 1024) as log:
        for i, c in enumerate(clouds):
            log.point_cloud("/dough", i * 1000, c)
            log.json("/actions", i * 1000, {"step": i, "tool": "knife", "action": [0.0, float(i), 0.0]})
    return clouds


@pytest.mark.parametrize("fraction", [0.5, 0.23, 0.9])
def test_cut_file_clear_error_and_recover(tmp_path, fraction):
    full = tmp_path / "full.mcap"
    clouds = _write(full)
    data = full.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])

    with pytest.raises(McapTruncatedError) as exc:
        RunReader(cut)
    text = str(exc.value)
    assert "cut.mcap" in text and "truncated" in text and "--recover" in text

    r = RunReader(cut, recover=True)
    assert not r.complete and r.recover_error
    got = list(r.messages("/dough"))
    assert 0 < len(got) < len(clouds)
    for k, (t, x) in enumerate(got):  # exactly the prefix, bitwise
        assert t == k * 1000 and x.tobytes() == clouds[k].tobytes()
    acts = list(r.messages("/actions"))
    assert [a["step"] for _, a in acts] == list(range(len(acts)))
    assert r.metadata() == {"seed": "1"}  # written before the first chunk
    assert r.config() == "a: 1\n"


def test_recover_on_complete_file_reads_everything(tmp_path):
    p = tmp_path / "full.mcap"
    clouds = _write(p, n=30)
    r = RunReader(p, recover=True)
    assert r.complete and r.recover_error is None
    assert len(list(r.messages("/dough"))) == len(clouds) == r.count("/dough")


def test_unfinished_writer_is_truncated(tmp_path):
    p = tmp_path / "killed.mcap"
    log = RunLogger(p, chunk_size=4096)
    for i in range(50):
        log.point_cloud("/dough", i, np.full((100, 3), i, np.float32))
    log.flush()  # like a process killed after flushing: no summary, no footer
    log._stream.flush()
    assert log.partial_path == tmp_path / "killed.mcap.partial" and not p.exists()
    with pytest.raises(McapTruncatedError):
        RunReader(log.partial_path)
    r = RunReader(log.partial_path, recover=True)
    assert len(list(r.messages("/dough"))) == 50 and r.status == "truncated"
    log.close()
    assert not log.partial_path.exists() and RunReader(p).status == "complete"


def _parse(argv):
    parser = argparse.ArgumentParser(prog="pasta replay")
    replay.add_arguments(parser)
    return parser.parse_args(argv)


def test_replay_cli_truncated(tmp_path, capsys):
    full = tmp_path / "full.mcap"
    _write(full)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full.read_bytes()[: full.stat().st_size // 2])

    assert replay.run(_parse([str(cut)])) == replay.EXIT_BAD_FILE
    err = capsys.readouterr().err
    assert "truncated" in err and "--recover" in err and "Traceback" not in err

    assert replay.run(_parse([str(cut), "--recover"])) == 0
    cap = capsys.readouterr()
    assert "RECOVERED" in cap.out and "/dough" in cap.out
    assert "recovered" in cap.err


@pytest.mark.parametrize("back", [1, 4, 12, 20])  # the closing magic, the footer's CRC, its offsets, its opcode
def test_a_flipped_byte_at_the_end_is_corrupt_not_truncated_and_recover_says_what_it_skipped(tmp_path, capsys, back):
    from pasta.io import McapFormatError

    full = tmp_path / "full.mcap"
    clouds = _write(full, n=30)
    data = bytearray(full.read_bytes())
    data[len(data) - back] ^= 0x40
    bad = tmp_path / "flipped.mcap"
    bad.write_bytes(bytes(data))
    with pytest.raises(McapFormatError) as exc:
        RunReader(bad)
    assert not isinstance(exc.value, McapTruncatedError)
    assert "is corrupt" in str(exc.value) and "truncated" not in str(exc.value) and "--recover" in str(exc.value)
    r = RunReader(bad, recover=True)
    assert r.count("/dough") == len(clouds)  # every message is in the whole data section
    assert "skipped the summary and footer" in r.recover_error
    assert replay.run(_parse([str(bad), "--recover"])) == 0
    assert "warning: recovered 61 messages from a damaged file; the data section is whole" in capsys.readouterr().err


def test_recover_of_a_cut_file_says_how_many_bytes_it_skipped(tmp_path):
    full = tmp_path / "full.mcap"
    _write(full)
    cut = tmp_path / "cut.mcap"
    data = full.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    r = RunReader(cut, recover=True)
    assert "skipped the last" in r.recover_error and r.recover_error.endswith(f"bytes of {len(data) // 2}")
