"""A record without its set point: read with the mean PV in its place, and said so."""

import json

import numpy as np
import pytest

from stiction_ros.analysis.detection.detect import detect, NO_SET_POINT
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions


@pytest.fixture(scope='module')
def record():
    from stiction_ros.sim.corpus import draw_scenario, simulate
    # A sticky self-regulating loop of the training seeds that the detector judges.
    for seed in range(40):
        sc = draw_scenario(seed)
        if not sc.label or sc.integrating:
            continue
        rec = simulate(sc)
        if detect(rec['op'], rec['pv'], rec['sp'], sc.sample_time).probability is not None:
            return sc, rec
    pytest.fail('no judged sticky loop among seeds 0-39')


def test_the_answer_without_sp_says_what_stood_in_for_it(record):
    sc, rec = record
    given = detect(rec['op'], rec['pv'], rec['sp'], sc.sample_time)
    absent = detect(rec['op'], rec['pv'], None, sc.sample_time)
    assert NO_SET_POINT not in given.evidence and 'set_point_given' not in given.details
    assert NO_SET_POINT in absent.evidence and absent.details['set_point_given'] is False
    # A caveat after the findings: the last one.
    assert absent.evidence[-1] == NO_SET_POINT and len(absent.evidence) > 1
    # The same trend with SP equal to the mean PV is what the detector read.
    same = detect(rec['op'], rec['pv'], np.full(len(rec['pv']), np.mean(rec['pv'])),
                  sc.sample_time)
    assert absent.probability == pytest.approx(same.probability, abs=1e-9)


def test_a_csv_without_an_sp_column_reports_it_in_the_json(record, tmp_path):
    sc, rec = record
    path = tmp_path / 'FIC101.csv'
    t = np.arange(len(rec['op'])) * sc.sample_time
    np.savetxt(path, np.column_stack([t, rec['op'], rec['pv']]), delimiter=',',
               header='t,op,pv', comments='', fmt='%.10g')
    out = tmp_path / 'FIC101.json'
    analyze_file(AnalyzeOptions(input=str(path), hammerstein=False, json_path=str(out)))
    det = json.loads(out.read_text())['stiction']['detector']
    assert det['set_point_given'] is False and NO_SET_POINT in det['evidence']
