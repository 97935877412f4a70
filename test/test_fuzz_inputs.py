"""
Fuzz every file the analyzer reads: CSVs, historian exports and bags, random and mutated.

Each input must end in one of two ways: a one-line :class:`InputError` (the
bag reader's own ``BagReadError`` for :func:`read_bag`), or a result that is
correct as far as it goes.  For bags that is checked message by message: a
damaged bag yields a subset of the original messages, and a warning whenever
any are missing.  Never a traceback, never a hang (30 s alarm per input) and
never more memory than ``MEMORY_BOUND`` (Python and numpy allocations, traced).

The inputs are the same on every run (``derandomize``), so CI is repeatable;
``FUZZ_EXAMPLES=5000 FUZZ_RANDOM=1 pytest test/test_fuzz_inputs.py`` explores
further.  The session summary prints how many inputs were tried.
"""

from collections import Counter
from datetime import datetime, timedelta
import os
from pathlib import Path
import shutil
import signal
import struct
import tempfile
import tracemalloc

from data_paths import plant_loops_dir
from hypothesis import given
from hypothesis import HealthCheck, settings, strategies as st
import numpy as np
import pytest
from stiction_ros.analysis.readers import InputError, load_record
from stiction_ros.bag.reader import BagReadError, read_bag
from stiction_ros.bag.writer import BagWriter
from test_analysis_inputs import check_invariants, historian_text

EXAMPLES = int(os.environ.get('FUZZ_EXAMPLES', '120'))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, database=None,
                derandomize=not os.environ.get('FUZZ_RANDOM'),
                suppress_health_check=list(HealthCheck))
# What the README promises: 64 MiB plus 50 bytes per byte of input.
MEMORY_BOUND = 64 * 2**20
PER_BYTE = 50
TRIED = Counter()
OUTCOMES = Counter()


class Hang(Exception):
    """An input took longer than the alarm."""


def _alarm(signum, frame):
    raise Hang('no result within 30 s')


def _size(path):
    path = Path(path)
    return sum(f.stat().st_size for f in path.rglob('*') if f.is_file()) if path.is_dir() \
        else path.stat().st_size


def attempt(kind, call, path, errors):
    """Run ``call(path)`` under the alarm and traced memory; return (result, error text)."""
    TRIED[kind] += 1
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(30)
    tracemalloc.start()
    result = error = None
    try:
        result = call(path)
    except errors as err:
        error = str(err)
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    bound = MEMORY_BOUND + PER_BYTE * _size(path)
    assert peak < bound, f'{peak / 2**20:.1f} MiB for {_size(path)} bytes of input'
    if error is not None:
        assert error.strip() and '\n' not in error, f'not one line: {error!r}'
        OUTCOMES[f'{kind}: one-line error'] += 1
    else:
        OUTCOMES[f'{kind}: result'] += 1
    return result, error


def analyse(kind, path):
    """Load ``path`` as the analyzer does; a record must satisfy the record invariants."""
    rec, _ = attempt(kind, load_record, path, InputError)
    if rec is not None:
        check_invariants(rec)
    return rec


# ---- byte- and line-level mutations shared by every format -----------------------------

@st.composite
def mutated(draw, data):
    """Return ``data`` (bytes) with one to four random edits."""
    data = bytearray(data)
    # Positions uniform over the file: hypothesis's own integers favour small values,
    # which would put most edits in the first bytes.
    rnd = draw(st.randoms(use_true_random=True))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(['flip', 'truncate', 'delete', 'insert', 'duplicate',
                                     'zero']))
        at = rnd.randrange(max(len(data), 1))
        if kind == 'flip' and data:
            data[at] ^= 1 << draw(st.integers(0, 7))
        elif kind == 'truncate':
            del data[at:]
        elif kind == 'delete':
            del data[at:at + draw(st.integers(1, 64))]
        elif kind == 'insert':
            data[at:at] = draw(st.binary(min_size=1, max_size=32) | st.sampled_from(
                [b'\x00', b'\xff\xfe', b'"', b'\r\n', b'\t', b',', b'nan', b'\xe4\xb8']))
        elif kind == 'duplicate':
            data[at:at] = data[at:at + draw(st.integers(1, 200))]
        elif kind == 'zero':
            data[at:at + draw(st.integers(1, 32))] = b'\x00' * len(data[at:at + 32])
    return bytes(data)


@st.composite
def line_edits(draw, text):
    """Return ``text`` with whole lines or fields removed, repeated, swapped or replaced."""
    lines = text.splitlines()
    rnd = draw(st.randoms(use_true_random=True))
    for _ in range(draw(st.integers(1, 3))):
        if not lines:
            break
        i = rnd.randrange(len(lines))
        kind = draw(st.sampled_from(['drop', 'repeat', 'swap', 'field']))
        if kind == 'drop':
            del lines[i]
        elif kind == 'repeat':
            lines.insert(i, lines[i])
        elif kind == 'swap':
            j = rnd.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        else:
            sep = '\t' if '\t' in lines[i] else ','
            fields = lines[i].split(sep)
            f = rnd.randrange(len(fields))
            fields[f] = draw(st.sampled_from(['', 'nan', '-inf', '1e999', 'abc', '12:00',
                                              '2024-13-45 25:61:61', '0', '-1e308', '"']))
            lines[i] = sep.join(fields)
    return '\n'.join(lines) + '\n'


# ---- CSV ------------------------------------------------------------------------------

NAMES = st.sampled_from(['t', 'T ', 'time', 'op', ' OP', 'mv', 'pv', 'sp', 'note', '', 'op',
                         'Timestamp', 'Time (ms)', 'FIC1.OP', 'FIC1_PV', 'FIC2.OP', 'X.MV'])
CELLS = st.one_of(
    st.floats(-1e3, 1e3).map(repr), st.floats().map(repr), st.integers(-10**20, 10**20).map(str),
    st.sampled_from(['', 'nan', 'inf', '-inf', '1e400', '0x10', '1,5', '--', '"a,b"', '2024',
                     'No Data', '1.234,5', '2026-03-01 12:00:00', '3/1/2026 1:00 PM', '12:00']),
    st.text(max_size=6))


def _time_text(t, form):
    # The time column as seconds, or as the dates historians write.
    if form == 'seconds':
        return repr(t)
    try:
        stamp = datetime(2026, 3, 1) + timedelta(seconds=t)
    except OverflowError:
        return repr(t)
    return stamp.strftime({'iso': '%Y-%m-%d %H:%M:%S', 'zone': '%Y-%m-%dT%H:%M:%SZ',
                           'dotted': '%d.%m.%Y %H:%M:%S', 'us': '%m/%d/%Y %I:%M:%S %p'}[form])


@st.composite
def csv_texts(draw):
    """Return CSV text: a drawn header and rows, mostly with a usable t column."""
    header = draw(st.lists(NAMES, max_size=6))
    if draw(st.booleans()):
        header = ['t', 'op'] + header
    delim = draw(st.sampled_from([',', ';', '\t']))
    form = draw(st.sampled_from(['seconds', 'seconds', 'iso', 'zone', 'dotted', 'us']))
    t = 0.0
    rows = [delim.join(header)]
    for _ in range(draw(st.integers(0, 60))):
        t += draw(st.sampled_from([1.0, 1.0, 1.0, 0.5, 2.0, 0.0, -1.0, 3.0, 7.0]))
        cells = [draw(CELLS) for _ in range(max(len(header) - 1, 0) + draw(st.integers(-1, 1)))]
        rows.append(delim.join([_time_text(t, form)] + cells))
    return '\n'.join(rows) + draw(st.sampled_from(['\n', '', '\r\n']))


def _valid_csv(n=80):
    k = np.arange(n)
    rows = ['t,op,mv,pv,sp'] + [f'{t:.1f},{50 + 5 * np.sin(t / 7):.4f},'
                                f'{50 + 4 * np.sin(t / 7):.4f},{np.cos(t / 7):.4f},0' for t in k]
    return '\n'.join(rows) + '\n'


@FUZZ
@given(text=csv_texts())
def test_generated_csvs(text):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / 'loop.csv'
        path.write_text(text, encoding='utf-8')
        analyse('csv', path)


@FUZZ
@given(data=st.one_of(mutated(_valid_csv().encode()), line_edits(_valid_csv()).map(str.encode),
                      st.binary(max_size=400)))
def test_mutated_csvs(data):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / 'loop.csv'
        path.write_bytes(data)
        analyse('csv', path)


# ---- historian exports -----------------------------------------------------------------

def _historian_seeds():
    seeds = [historian_text(n=120).encode('utf-8')]
    plant = plant_loops_dir()
    if plant is not None:
        first = sorted((plant / 'stiction').glob('*.txt'))[0]
        seeds.append(b''.join(first.read_bytes().splitlines(keepends=True)[:200]))
    return seeds


HISTORIAN = _historian_seeds()


@FUZZ
@given(seed=st.sampled_from(range(len(HISTORIAN))), edit=st.data())
def test_mutated_historian_exports(seed, edit):
    base = HISTORIAN[seed]
    if edit.draw(st.booleans()):
        data = edit.draw(mutated(base))
    else:
        data = edit.draw(line_edits(base.decode('utf-8', errors='replace'))).encode('utf-8')
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / 'export.txt'
        path.write_bytes(data)
        analyse('historian', path)


# ---- bags -------------------------------------------------------------------------------

def _cdr_float(x):
    return b'\x00\x01\x00\x00' + struct.pack('<d', x)


def _cdr_string(s):
    raw = s.encode() + b'\x00'
    return b'\x00\x01\x00\x00' + struct.pack('<I', len(raw)) + raw


def write_bag(directory, compression='zstd', n=120, op_type='std_msgs/msg/Float64'):
    """Write a small loop bag with several chunks; return its directory."""
    w = BagWriter(directory, compression=compression, chunk_size=1024)
    for name in ('op', 'mv', 'pv', 'sp'):
        w.add_topic(f'/loop/{name}', op_type if name == 'op' else 'std_msgs/msg/Float64', [])
    w.add_topic('/loop/status', 'std_msgs/msg/String', [])
    for k in range(n):
        t = int((k + 0.5) * 1e9)
        op = 50 + 5 * np.sin(k / 7)
        w.write('/loop/op', _cdr_string(f'{op}') if op_type.endswith('String') else
                _cdr_float(op), t)
        w.write('/loop/mv', _cdr_float(round(op - 1, 1)), t + 250_000_000)
        w.write('/loop/pv', _cdr_float(np.cos(k / 7)), t - 250_000_000)
        w.write('/loop/sp', _cdr_float(0.0), t)
        if k % 40 == 0:
            w.write('/loop/status', _cdr_string(f'sample {k}'), t)
    w.close()
    return directory


ORIGINALS = {}


def original(compression):
    """Return (mcap bytes, metadata.yaml text, record offsets, messages by topic) of a bag."""
    if compression not in ORIGINALS:
        with tempfile.TemporaryDirectory() as d:
            bag = write_bag(Path(d) / 'bag', compression)
            data = next(bag.glob('*.mcap')).read_bytes()
            meta = (bag / 'metadata.yaml').read_text()
            got = read_bag(bag)
        offsets, pos = [], 8
        while pos + 9 <= len(data):
            offsets.append(pos)
            pos += 9 + int.from_bytes(data[pos + 1:pos + 9], 'little')
        messages = {name: set(zip(t.log_time.tolist(), t.data)) for name, t in got.topics.items()}
        ORIGINALS[compression] = data, meta, offsets, messages
    return ORIGINALS[compression]


HUGE = [2**64 - 1, 2**63, 2**40, 256 * 2**20 + 1, 10**6]


@st.composite
def damaged_bags(draw):
    """Return (compression, mcap bytes): flipped, truncated, or with forged length fields."""
    compression = draw(st.sampled_from(['zstd', 'lz4', 'none']))
    data, _, offsets, _ = original(compression)
    how = draw(st.sampled_from(['bytes', 'bytes', 'length', 'chunk_size']))
    if how == 'bytes':
        return compression, draw(mutated(data))
    data = bytearray(data)
    rnd = draw(st.randoms(use_true_random=True))
    at = rnd.choice(offsets)
    if how == 'chunk_size':
        chunks = [o for o in offsets if data[o] == 0x06]
        at = rnd.choice(chunks) + 9 + 16                 # uncompressed_size of a chunk
    else:
        at += 1                                          # a record's length field
    value = draw(st.sampled_from(HUGE) | st.integers(0, 2**64 - 1))
    data[at:at + 8] = value.to_bytes(8, 'little')
    return compression, bytes(data)


def _bag_dir(d, data, meta):
    bag = Path(d) / 'bag'
    bag.mkdir()
    (bag / 'bag_0.mcap').write_bytes(data)
    if meta is not None:
        (bag / 'metadata.yaml').write_text(meta)
    return bag


@FUZZ
@given(case=damaged_bags(), keep_meta=st.booleans())
def test_damaged_bags_yield_a_subset_of_their_messages_with_a_warning(case, keep_meta):
    compression, data = case
    _, meta, _, messages = original(compression)
    with tempfile.TemporaryDirectory() as d:
        bag = _bag_dir(d, data, meta if keep_meta else None)
        got, error = attempt('bag (reader)', read_bag, bag, BagReadError)
        if got is None:
            return
        missing = 0
        for name, topic in got.topics.items():
            pairs = set(zip(topic.log_time.tolist(), topic.data))
            assert pairs <= messages.get(name, set()), f'{name}: messages not in the original'
            missing += len(messages.get(name, ())) - len(pairs)
        missing += sum(len(v) for n, v in messages.items() if n not in got.topics)
        if missing:
            assert got.warnings or not got.complete, f'{missing} messages lost without a warning'


@FUZZ
@given(case=damaged_bags())
def test_damaged_bags_through_the_analyzer(case):
    compression, data = case
    with tempfile.TemporaryDirectory() as d:
        analyse('bag (analyzer)', _bag_dir(d, data, original(compression)[1]))


@FUZZ
@given(meta=st.one_of(st.text(max_size=300), mutated(original('zstd')[1].encode()).map(
    lambda b: b.decode('utf-8', errors='replace'))))
@pytest.mark.slow
def test_a_damaged_metadata_yaml_does_not_matter_when_the_mcap_is_whole(meta):
    data = original('zstd')[0]
    with tempfile.TemporaryDirectory() as d:
        rec = analyse('bag (metadata.yaml)', _bag_dir(d, data, meta))
        assert rec is not None and rec.samples == 120


@pytest.mark.parametrize('case', ['no metadata.yaml', 'zero messages', 'op is a String',
                                  'empty mcap', 'metadata names a missing file',
                                  'metadata names a file outside', 'no mcap at all'])
def test_structural_faults_of_bags(tmp_path, case):
    bag = tmp_path / 'bag'
    write_bag(bag, n=0 if case == 'zero messages' else 120,
              op_type='std_msgs/msg/String' if case == 'op is a String' else
              'std_msgs/msg/Float64')
    mcap = bag / 'bag_0.mcap'
    if case == 'no metadata.yaml':
        (bag / 'metadata.yaml').unlink()
    elif case == 'empty mcap':
        mcap.write_bytes(b'')
    elif case.startswith('metadata names'):
        # An existing bag beside this one, of other length: were it followed, 30 samples.
        target = 'gone.mcap' if 'missing' in case else '../other/other_0.mcap'
        write_bag(tmp_path / 'other', n=30)
        meta = (bag / 'metadata.yaml').read_text().replace('bag_0.mcap', target)
        (bag / 'metadata.yaml').write_text(meta)
    elif case == 'no mcap at all':
        shutil.move(mcap, tmp_path / 'elsewhere.mcap')
    rec = analyse('bag (structure)', bag)
    if case in ('no metadata.yaml', 'metadata names a missing file',
                'metadata names a file outside'):
        assert rec is not None and rec.samples == 120    # the .mcap beside it is read
    else:
        assert rec is None
