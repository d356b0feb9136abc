"""One round-trip test base for every file format (python-can's ReaderWriterTest idea).

Each format plugs in a writer, a reader, sample data and how to compare; the same tests
then hold for all of them: what is written reads back equal, writing is deterministic
where the format allows it, and a damaged file (cut in the middle of a line or array, or
not the format at all) is a :class:`bmg160_emu.io.FormatError` whose message names the file.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bmg160_emu.io import FormatError, format_for
from bmg160_emu.io.dump import RegisterDump, format_dump, parse_dump
from bmg160_emu.io.formats import block_writer_for
from bmg160_emu.io.rates import load_rate_record, write_rates
from bmg160_emu.io.recording import Recording, read_recording, write_recording
from bmg160_emu.io.trace import TraceHeader, TraceWriter, read_trace
from bmg160_emu.traffic.transaction import Transaction


@dataclass(frozen=True)
class FormatCase:
    """One format under test: write ``sample()`` to a path, read it back, compare."""

    name: str
    suffix: str
    sample: Callable[[], Any]
    write: Callable[[Path, Any], None]
    read: Callable[[Path], Any]
    same: Callable[[Any, Any], bool]
    deterministic: bool = True  # NPZ members carry the time they were written
    kind: str | None = None  # the registry kind, when the format is registered by suffix


def _rates_sample() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(11)
    return 0.005 * np.arange(1, 301), rng.normal(0.0, 0.3, (300, 3))


def _write_rates(path: Path, sample) -> None:
    t, rate = sample
    write_rates(path, None if path.suffix == ".npy" else t, rate, comments=["round trip"])


def _read_rates(path: Path):
    return load_rate_record(path, rate_hz=200.0)


def _same_rates(sample, record) -> bool:
    return np.array_equal(record.rate_dps, sample[1]) and record.rate_hz == pytest.approx(200.0)


def _write_stream(path: Path, sample) -> None:
    _, rate = sample
    with open(path, "wb") as handle:  # in two blocks, as generate streams a long record
        writer = block_writer_for("rate stream", path)(handle, len(rate), 200.0, ["stream"])
        writer.write(0, rate[:120])
        writer.write(120, rate[120:])


def _same_streamed(sample, record) -> bool:
    # CSV keeps 10 significant digits (%.10g): equal to 1e-10 relative, the time exact
    return (np.allclose(record.rate_dps, sample[1], rtol=1e-9, atol=0)
            and record.rate_hz == pytest.approx(200.0))


def _recording_sample() -> Recording:
    rng = np.random.default_rng(5)
    n = 200
    return Recording(0.005 * np.arange(1, n + 1), rng.integers(-32768, 32768, (n, 3)), 16.384,
                     rng.normal(size=(n, 3)), {"odr_hz": 200.0, "range_dps": 2000, "seed": 5})


def _same_recording(a: Recording, b: Recording) -> bool:
    return (np.array_equal(a.t_s, b.t_s) and np.array_equal(a.counts, b.counts)
            and np.array_equal(a.true_rate_dps, b.true_rate_dps)
            and a.lsb_per_dps == b.lsb_per_dps and a.metadata == b.metadata)


def _trace_sample():
    header = TraceHeader(seed=7)
    header.add_chip({"address": 0x68}, (1.0, 0.0, -2.5), [(0x0F, b"\x03")])
    records = [
        Transaction(0.001 * k, 1, 0x68, "read_i2c_block_data", register=0x02, read=bytes(range(k, k + 6))).to_dict()
        for k in range(20)
    ]
    return header, records


def _write_trace(path: Path, sample) -> None:
    header, records = sample
    with TraceWriter(path, header) as writer:
        writer.write_all(records)


def _same_trace(sample, back) -> bool:
    header, records = sample
    read_header, read_records = back
    stripped = [{k: v for k, v in r.items() if k != "_line"} for r in read_records]
    fields = {k: v for k, v in read_header.items() if k != "_partial"}  # what the reader found
    return fields == header.to_dict() and stripped == records and read_header["_partial"] is None


def _dump_sample() -> RegisterDump:
    return RegisterDump(bytes((7 * k + 3) % 256 for k in range(64)), address=0x68, time_s=1.5)


def _dump_case(fmt: str) -> FormatCase:
    def write(path: Path, dump) -> None:
        path.write_text(format_dump(dump, fmt), encoding="utf-8")

    def read(path: Path):
        return parse_dump(path.read_text(encoding="utf-8"), str(path))

    return FormatCase(f"dump-{fmt}", ".txt", _dump_sample, write, read,
                      lambda a, b: a.values == b.values)


CASES = [
    *(FormatCase(f"rates{s}", s, _rates_sample, _write_rates, _read_rates, _same_rates,
                 deterministic=s != ".npz", kind="rates") for s in (".csv", ".npz", ".npy")),
    *(FormatCase(f"rate-stream{s}", s, _rates_sample, _write_stream, _read_rates, _same_streamed,
                 kind="rate stream") for s in (".csv", ".npy")),
    *(FormatCase(f"recording{s}", s, _recording_sample, lambda p, r: write_recording(r, p),
                 read_recording, _same_recording, deterministic=s != ".npz", kind="recording")
      for s in (".csv", ".npz")),
    FormatCase("trace", ".jsonl", _trace_sample, _write_trace, read_trace, _same_trace,
               kind="trace"),
    *(_dump_case(fmt) for fmt in ("i2cdump", "table", "json")),
]


@pytest.fixture(params=CASES, ids=lambda case: case.name)
def case(request) -> FormatCase:
    return request.param


def test_what_is_written_reads_back_the_same(case, tmp_path):
    path = tmp_path / f"f{case.suffix}"
    sample = case.sample()
    case.write(path, sample)
    assert case.same(sample, case.read(path))


def test_writing_the_same_data_twice_gives_the_same_bytes(case, tmp_path):
    if not case.deterministic:
        pytest.skip("NPZ members carry their write time (zipfile)")
    a, b = tmp_path / f"a{case.suffix}", tmp_path / f"b{case.suffix}"
    case.write(a, case.sample())
    case.write(b, case.sample())
    assert a.read_bytes() == b.read_bytes()


def test_a_file_cut_short_is_a_format_error_naming_the_file(case, tmp_path):
    path = tmp_path / f"f{case.suffix}"
    case.write(path, case.sample())
    data = path.read_bytes()
    cut = len(data) // 2
    if case.suffix == ".csv":
        # just after a comma: the last row lacks cells (a CSV cut inside a number is a
        # shorter number, which no reader can tell)
        cut = data.index(b",", cut) + 1
    elif case.suffix not in (".npz", ".npy"):
        cut = data.index(b"\n", cut) - 3  # inside a line, not at its end
    path.write_bytes(data[:cut])
    with pytest.raises(FormatError, match=path.name):
        case.read(path)


def test_a_file_of_another_kind_is_a_format_error_naming_the_file(case, tmp_path):
    path = tmp_path / f"f{case.suffix}"
    path.write_bytes(b"PK\x03\x04 this is not it\n{\n" if case.suffix != ".npz" else b"x,y\n1,2\n")
    with pytest.raises(FormatError, match=path.name):
        case.read(path)


def test_the_registry_gives_the_reader_and_writer_of_the_suffix(case):
    if case.kind is None:
        pytest.skip("read and written by name, not looked up by suffix")
    fmt = format_for(case.kind, Path(f"any{case.suffix}"), writing=True)
    assert fmt.writer is not None and fmt.suffix == case.suffix
    if case.kind != "rate stream":  # a stream is read back as rates (the case's reader)
        assert fmt.reader is not None


def test_an_unknown_suffix_names_the_known_ones():
    with pytest.raises(FormatError, match=r"rates file must end in \.csv, \.npy, \.npz or \.resd, not 'a\.txt'"):
        format_for("rates", Path("a.txt"), writing=True)
    with pytest.raises(FormatError, match=r"output must end in \.npy, \.csv or \.resd, not 'a\.h5'"):
        format_for("rate stream", Path("a.h5"), writing=True, what="output")
    assert format_for("rates", Path("a.txt"), reading=True).writer is None  # UART or CSV


def test_every_kind_is_served_by_the_registry_over_the_common_bases():
    # python-can's LogReader/Logger idea: by kind and suffix, one registry; every reader a
    # FileReader, every whole-file writer a FileWriter, every stream a BlockWriter
    from bmg160_emu.io.formats import BlockWriter, FileReader, FileWriter, suffixes

    expected = {"rates": (".csv", ".npy", ".npz", ".resd", ".txt", ".log"),
                "rate table": (".csv", ".npy"), "rate stream": (".npy", ".csv", ".resd"),
                "recording": (".csv", ".npz", ".resd"),
                "replay": (".csv", ".txt", ".log", ".npz"), "trace": (".jsonl",)}
    for kind, known in expected.items():
        assert suffixes(kind) == known, kind
        for suffix in known:
            fmt = format_for(kind, Path(f"f{suffix}"))
            if kind == "trace":
                continue  # a JSON Lines sink of its own (TraceWriter), read by read_trace
            if fmt.reader is not None:
                assert issubclass(fmt.reader, FileReader), (kind, suffix)
            if fmt.writer is not None:
                base = BlockWriter if kind == "rate stream" else FileWriter
                assert issubclass(fmt.writer, base), (kind, suffix)


def test_every_format_error_is_a_value_error():
    from bmg160_emu.io.dump import DumpFormatError
    from bmg160_emu.io.rate_table import RateFileError
    from bmg160_emu.io.trace import TraceFormatError

    for error in (DumpFormatError, RateFileError, TraceFormatError):
        assert issubclass(error, FormatError) and issubclass(error, ValueError)


def test_csv_blank_lines_comments_and_lines_of_spaces_are_skipped_and_lines_still_named(tmp_path):
    from bmg160_emu.io.rate_table import RateFileError

    path = tmp_path / "r.csv"
    path.write_text("t,x\n0,1\n \t \n0.005,2 # a note\n# a comment\n\n0.01,3\n0.015,x\n")
    with pytest.raises(RateFileError, match=r"r\.csv:8: not a number: 'x'"):
        load_rate_record(path)
    path.write_text("t,x\n0,1\n \t \n0.005,2 # a note\n# a comment\n\n0.01,3\n0.005,4\n")
    with pytest.raises(RateFileError, match=r"r\.csv:8: time 0\.005 s is not after 0\.01 s"):
        load_rate_record(path)
    path.write_text("t,x\n0,1\n \t \n0.005,2 # a note\n# a comment\n\n0.01,3\n")
    assert load_rate_record(path).rate_dps.ravel().tolist() == [1.0, 2.0, 3.0]
