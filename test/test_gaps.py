"""A record cut into stretches: the pooled answer, and the study that scores it."""

import json
import math

import numpy as np
import pytest

from stiction_ros.analysis.detection.stretches import logit, pooled_probability
from stiction_ros.study.gaps import answers, gap_of, MARGIN, SHARES


def test_pooled_odds_lie_between_the_stretches_and_weigh_them_by_length():
    assert pooled_probability([0.8], [300]) == pytest.approx(0.8)
    # Stretches that agree give their own reading, not a stronger one.
    assert pooled_probability([0.9, 0.9], [200, 500]) == pytest.approx(0.9)
    p = pooled_probability([0.9, 0.2], [600, 200])
    assert 0.2 < p < 0.9
    # The longer stretch pulls harder; equal lengths meet at the mean log-odds.
    assert p > pooled_probability([0.9, 0.2], [200, 600])
    mean = (logit(0.9) + logit(0.2)) / 2
    assert pooled_probability([0.9, 0.2], [300, 300]) == pytest.approx(1 / (1 + math.exp(-mean)))
    # Symmetric: stiction and no stiction swap places exactly.
    assert pooled_probability([0.1, 0.8], [300, 400]) == pytest.approx(
        1 - pooled_probability([0.9, 0.2], [300, 400]))
    assert pooled_probability([0.0, 1.0], [100, 100]) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        pooled_probability([], [])
    with pytest.raises(ValueError):
        pooled_probability([0.5], [0])


@pytest.mark.parametrize('share', SHARES)
def test_the_gap_keeps_clear_of_both_ends_and_takes_its_share(share):
    for seed in range(50):
        a, b = gap_of(1000, share, seed)
        assert b - a == round(share * 1000)
        assert a >= MARGIN * 1000 and b <= (1 - MARGIN) * 1000


def test_the_longest_stretch_answers_alone_and_the_pool_uses_every_judged_one():
    longest, pooled = answers([(400, 0.3), (500, None)])
    assert np.isnan(longest) and pooled == pytest.approx(0.3)
    longest, pooled = answers([(400, 0.3), (500, 0.8)])
    assert longest == 0.8 and pooled == pytest.approx(pooled_probability([0.3, 0.8], [400, 500]))
    assert all(np.isnan(v) for v in answers([(50, None), (60, None)]))


@pytest.mark.slow
def test_the_study_scores_the_records_make_accuracy_scores(tmp_path):
    from stiction_ros.analysis.detection import dataset, deadband_like
    from stiction_ros.cli.gaps import main
    seeds = range(3_600_000, 3_600_010)
    md, js = tmp_path / 'g.md', tmp_path / 'g.json'
    assert main(['--first-seed', str(seeds.start), '--seeds', '10', '--jobs', '1',
                 '--markdown', str(md), '--json', str(js)]) == 0
    study = json.loads(js.read_text())
    acc = deadband_like.leave_out(deadband_like.mark(dataset.build(seeds, progress=False)))
    assert study['records'] == len(acc['y']) and study['sticky'] == int(acc['y'].sum())
    assert len(study['rows']) == 3 * len(SHARES)
    for r in study['rows']:
        assert r['tp'] + r['fn'] == study['sticky']
        if r['rule'] == 'whole record':
            assert r['refused'] == 0 and r['differ_from_whole'] == 0
    assert '| 20% | every stretch pooled |' in md.read_text()


def _gapped_csv(path, seed, gap=(0.45, 0.55)):
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(seed)
    rec = simulate(sc)
    n = len(rec['op'])
    a, b = int(gap[0] * n), int(gap[1] * n)
    lines = ['t,op,pv,sp']
    for k in range(n):
        cells = ('', '') if a <= k < b else (f'{rec["op"][k]:.6f}', f'{rec["pv"][k]:.6f}')
        lines.append(f'{k * sc.sample_time:g},{cells[0]},{cells[1]},{rec["sp"][k]:.6f}')
    path.write_text('\n'.join(lines) + '\n')
    return sc, a, b


@pytest.mark.slow
@pytest.mark.parametrize('seed', [3_600_008, 3_600_015])
def test_a_record_with_a_gap_is_judged_on_both_stretches_pooled(tmp_path, seed):
    from stiction_ros.analysis.detection.detect import detect
    from stiction_ros.analysis.pipeline import analyze, Options
    from stiction_ros.analysis.readers import load_record
    sc, a, b = _gapped_csv(tmp_path / 'gap.csv', seed)
    record = load_record(tmp_path / 'gap.csv')
    report = analyze(record, Options(hammerstein=False)).report
    det = report['stiction']['detector']
    # The page says what the terminal's judged: line says.
    from stiction_ros.viz.report_html import render
    assert '<p>Judged on: the detector pooled 2 stretches between gaps' in render(report, [])
    # Each stretch read alone, as the analyzer reads a record of its own.
    op, pv, sp = (record.signals[k] for k in ('op', 'pv', 'sp'))
    n = record.samples
    alone = [detect(op[lo:hi], pv[lo:hi], sp[lo:hi], sc.sample_time, sc.integrating)
             for lo, hi in ((0, a), (b, n))]
    table = det['stretches']
    longest = 0 if a >= n - b else 1
    assert [t['samples'] for t in table] == sorted([a, n - b], reverse=True)
    assert [t['probability'] for t in table] == [alone[longest].probability,
                                                 alone[1 - longest].probability]
    want = pooled_probability([d.probability for d in alone], [a, n - b])
    assert det['probability'] == pytest.approx(want, abs=1e-4)
    assert det['evidence'][0].startswith('2 stretches between gaps, each judged alone: 0-')
    # The evidence's times are the record's: within the stretch it came from.
    lo, hi = (0, a) if longest == 0 else (b, n)
    assert det['stuck']['stuck_periods_s']
    for start, end, _ in det['stuck']['stuck_periods_s']:
        assert lo * sc.sample_time <= start < end <= hi * sc.sample_time


def test_the_judged_line_says_which_stretches_the_answer_came_from():
    from stiction_ros.app.report_text import judged_text
    win = {'start_s': 0.0, 'end_s': 3990.0, 'samples': 400, 'held': 0}

    def report(*parts):
        return {'valid_samples': 700, 'signature_window': win, 'stiction': {'detector': {
            'stretches': [{'start_s': s, 'end_s': e, 'samples': n, 'probability': p,
                           'not_judged': c} for s, e, n, p, c in parts]}}}
    both = report((0.0, 3990.0, 400, 0.8, ''), (5000.0, 7990.0, 300, 0.6, ''))
    assert judged_text(both) == ('the detector pooled 2 stretches between gaps (700 of 700 '
                                 'valid samples); the signatures read the longest, 400 '
                                 'samples (0-3990 s)')
    other = report((0.0, 3990.0, 400, None, 'pv_constant'), (5000.0, 7990.0, 300, 0.6, ''))
    assert judged_text(other).startswith('the detector judged 300 of 700 valid samples '
                                         '(5000-7990 s) alone: the longest stretch')
    assert '(pv constant)' in judged_text(other)
    short = report((0.0, 3990.0, 400, 0.8, ''), (5000.0, 6490.0, 150, None, 'too_short'))
    assert judged_text(short).endswith('and 1 other stretch of 100 samples or more could not '
                                       'be judged alone (too short)')


@pytest.mark.slow
def test_a_longest_stretch_that_cannot_be_judged_leaves_the_answer_to_the_others(tmp_path):
    from stiction_ros.analysis.detection.detect import detect
    from stiction_ros.analysis.pipeline import analyze, Options
    from stiction_ros.analysis.readers import load_record
    from stiction_ros.app.report_text import judged_text
    sc, a, b = _gapped_csv(tmp_path / 'gap.csv', 3_600_008, gap=(0.6, 0.65))
    # The transmitter froze over the longest stretch: PV reads one value there.
    lines = (tmp_path / 'gap.csv').read_text().splitlines()
    for k in range(1, a + 1):
        t, op, _, sp = lines[k].split(',')
        lines[k] = f'{t},{op},25.0,{sp}'
    (tmp_path / 'gap.csv').write_text('\n'.join(lines) + '\n')
    record = load_record(tmp_path / 'gap.csv')
    report = analyze(record, Options(hammerstein=False)).report
    st = report['stiction']
    op, pv, sp = (record.signals[k] for k in ('op', 'pv', 'sp'))
    alone = detect(op[b:], pv[b:], sp[b:], sc.sample_time, sc.integrating)
    assert [t['not_judged'] for t in st['detector']['stretches']] == ['pv_constant', '']
    assert st['probability'] == alone.probability and st['answer'] == alone.answer
    # The size would read the frozen stretch, so none is given, and the reason says why.
    assert st['apparent_S'] is None and 'constant' in st['size_withheld'].lower()
    assert judged_text(report).startswith(f'the detector judged {record.samples - b} of ')


def test_valid_samples_in_stretches_too_short_to_read_are_counted_and_said():
    from stiction_ros.analysis.pipeline import short_stretches
    from stiction_ros.analysis.record import Record
    from stiction_ros.app.report_text import judged_text
    n = 1000
    t = np.arange(n) * 1.0
    valid = np.ones(n, bool)
    # A 950-sample stretch, then a gap, a 40-sample stretch, a gap, a 5-sample one.
    valid[950:953] = False
    valid[993:996] = False
    signals = {'op': np.linspace(0, 1, n), 'pv': np.linspace(0, 1, n)}
    record = Record(t=t, sample_time=1.0, signals=signals, valid=valid, name='r')
    short = short_stretches(record)
    assert short == {'stretches': 2, 'valid_samples': 40 + 4}
    win = {'start_s': 0.0, 'end_s': 949.0, 'samples': 950, 'held': 0}
    report = {'valid_samples': int(valid.sum()), 'signature_window': win,
              'short_stretches': short}
    # The longest holds over 90 % of the valid samples: only the short ones are named.
    assert judged_text(report) == ('44 valid samples in 2 stretches under 100 samples '
                                   'between gaps were not read')
    del report['short_stretches']
    assert judged_text(report) == ''
    # A record without gaps has none.
    assert short_stretches(Record(t=t, sample_time=1.0, signals=signals, valid=np.ones(n, bool),
                                  name='r')) == {}
