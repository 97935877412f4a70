"""The accuracy page's bootstrap intervals: against naive resampling, and what tags mean."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from stiction_ros.cli.accuracy import main
from stiction_ros.cli.accuracy_markdown import markdown, plant_calls
from stiction_ros.study.accuracy import balanced_accuracy, confusion
from stiction_ros.study.intervals import class_interval, exact_interval, tag_interval

DOCS = Path(__file__).resolve().parents[1] / 'docs'


def _naive_records(y, hit, draws, rng):
    # Resample the records of each class, one by one, and score the draw.
    pos, neg = np.flatnonzero(y), np.flatnonzero(~y)
    out = []
    for _ in range(draws):
        a, b = rng.choice(pos, len(pos)), rng.choice(neg, len(neg))
        out.append(0.5 * (hit[a].mean() + hit[b].mean()))
    return np.percentile(out, [2.5, 97.5])


def _naive_tags(y, hit, groups, draws, rng):
    tags = sorted(set(groups))
    out = []
    while len(out) < draws:
        drawn = rng.choice(len(tags), len(tags))
        rows = [i for t in drawn for i, g in enumerate(groups) if g == tags[t]]
        yy, hh = y[rows], hit[rows]
        if yy.any() and (~yy).any():
            out.append(0.5 * (hh[yy].mean() + hh[~yy].mean()))
    return np.percentile(out, [2.5, 97.5])


def test_the_class_bootstrap_agrees_with_resampling_records_one_by_one():
    y = np.array([True] * 40 + [False] * 90)
    hit = np.ones(130, dtype=bool)
    hit[[1, 5, 9, 30, 33, 60, 61, 62, 70, 80, 99, 120]] = False
    called = np.where(hit, y, ~y)
    c = confusion(y, called)
    lo, hi = class_interval(c, draws=4000)
    ref = _naive_records(y, hit, 4000, np.random.default_rng(1))
    # Two Monte Carlo draws of the same distribution: within their noise.
    assert lo == pytest.approx(ref[0], abs=0.012) and hi == pytest.approx(ref[1], abs=0.012)
    assert lo < balanced_accuracy(c) < hi


def test_the_class_interval_narrows_as_the_square_root_of_the_records():
    c = {'tp': 80, 'fn': 20, 'fp': 30, 'tn': 170}
    lo, hi = class_interval(c)
    lo4, hi4 = class_interval({k: 4 * v for k, v in c.items()})
    assert 1.6 < (hi - lo) / (hi4 - lo4) < 2.5


def test_resampling_cannot_doubt_a_perfect_class_and_one_class_has_no_figure():
    # The known limit the page states: no miss, no spread.
    assert class_interval({'tp': 10, 'fn': 0, 'fp': 0, 'tn': 7}) == (1.0, 1.0)
    assert all(math.isnan(v) for v in class_interval({'tp': 3, 'fn': 1, 'fp': 0, 'tn': 0}))
    assert all(math.isnan(v) for v in tag_interval([True, True], [True, False], ['a', 'b']))


def test_the_exact_interval_of_a_share_without_a_miss():
    # k = n: the lower bound solves p**n = (1 - level) / 2.
    lo, hi = exact_interval(15, 15)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / 15))
    # A share and its complement mirror each other.
    lo, hi = exact_interval(5, 17)
    lo_c, hi_c = exact_interval(12, 17)
    assert lo == pytest.approx(1 - hi_c) and hi == pytest.approx(1 - lo_c)
    assert lo < 5 / 17 < hi
    with pytest.raises(ValueError):
        exact_interval(3, 2)


def _plant_like():
    # Three sticky valves (one with many records, mostly missed), many healthy ones.
    groups = ['S1'] * 12 + ['S2'] * 3 + ['S3'] * 2 + [f'H{i}' for i in range(15) for _ in (0, 1)]
    y = np.array([g.startswith('S') for g in groups])
    hit = np.array([g != 'S1' for g in groups])
    hit[[0, 1]] = True
    hit[20] = False
    return y, hit, groups


def test_the_tag_bootstrap_agrees_with_drawing_tags_one_by_one():
    y, hit, groups = _plant_like()
    called = np.where(hit, y, ~y)
    lo, hi = tag_interval(y, called, groups, draws=4000)
    ref = _naive_tags(y, hit, groups, 4000, np.random.default_rng(1))
    assert lo == pytest.approx(ref[0], abs=0.02) and hi == pytest.approx(ref[1], abs=0.02)


def test_more_records_of_the_same_valves_do_not_narrow_the_tag_interval():
    y, hit, groups = _plant_like()
    called = np.where(hit, y, ~y)
    once = tag_interval(y, called, groups)
    thrice = tag_interval(np.tile(y, 3), np.tile(called, 3), groups * 3)
    assert thrice == once
    # Read as independent records, the same tripled set would look far surer.
    c3 = confusion(np.tile(y, 3), np.tile(called, 3))
    lo, hi = class_interval(c3)
    assert hi - lo < 0.5 * (once[1] - once[0])


def test_the_accuracy_page_is_the_rendering_of_its_json(tmp_path):
    study = json.loads((DOCS / 'accuracy.json').read_text(encoding='utf-8'))
    assert markdown(study) == (DOCS / 'ACCURACY.md').read_text(encoding='utf-8')
    out = tmp_path / 'page.md'
    assert main(['--render-only', '--json', str(DOCS / 'accuracy.json'),
                 '--markdown', str(out)]) == 0
    assert out.read_text(encoding='utf-8') == markdown(study)


def test_the_plant_intervals_are_about_the_rows_of_the_table():
    # The page recomputes the plant calls from the per-file answers; they must
    # be the calls the table scored, count for count.
    study = json.loads((DOCS / 'accuracy.json').read_text(encoding='utf-8'))
    y = [c['label'] for c in study['cases']]
    calls = plant_calls(study)
    assert len(calls) == 3
    for key, called in calls.items():
        row = study['plant'][key]
        assert confusion(y, called) == {k: row[k] for k in ('tp', 'fn', 'fp', 'tn')}, key


@pytest.mark.parametrize('text', ['{"plant": ', '[]', '{"plant": {}, "sim": {}, "cases": []}',
                                  '{"plant": {"a": 1}, "sim": [], "cases": []}',
                                  '{"plant": {"a": 1}, "sim": {}, "cases": [3]}'])
def test_an_unreadable_study_is_a_clear_error_and_leaves_the_page(tmp_path, capsys, text):
    bad = tmp_path / 'bad.json'
    bad.write_text(text, encoding='utf-8')
    page = tmp_path / 'x.md'
    page.write_text('the page before', encoding='utf-8')
    assert main(['--render-only', '--json', str(bad), '--markdown', str(page)]) == 2
    assert 'cannot render' in capsys.readouterr().err
    assert page.read_text(encoding='utf-8') == 'the page before'


def test_a_page_that_cannot_be_written_is_a_clear_error(tmp_path, capsys):
    assert main(['--render-only', '--json', str(DOCS / 'accuracy.json'),
                 '--markdown', str(tmp_path / 'missing' / 'x.md')]) == 2
    assert 'cannot write' in capsys.readouterr().err
