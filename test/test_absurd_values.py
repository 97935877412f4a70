"""
Values no instrument reads, in files and bags: excluded with the reason, never a traceback.

Historian and DCS exports write codes such as 9.99e37 or -1e30 for a bad value,
and a stray publisher can put a test message on a loop topic; squaring such a
number overflows every sum the analysis forms (a bag with one PV of 1e300 ended
in a math domain error).  The reader reads them as the loop's nodes would.
"""

import struct
import warnings

import numpy as np
from stiction_ros.analysis.pipeline import analyze, Options
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.record import NOT_A_MEASUREMENT
from stiction_ros.bag.metadata import qos_profile
from stiction_ros.bag.writer import BagWriter
from stiction_ros.sim.corpus import draw_scenario, simulate
from stiction_ros.sim.ros_params import INPUT_LIMIT

SEED = 3_600_008


def _loop():
    sc = draw_scenario(SEED)
    return sc, simulate(sc)


def test_bad_value_codes_in_a_csv_are_excluded_and_the_rest_analysed(tmp_path):
    sc, rec = _loop()
    pv = np.array(rec['pv'], float)
    codes = {40: 9.99e37, 41: -1e30, 300: 3.4e38}
    for k, v in codes.items():
        pv[k] = v
    lines = ['t,op,pv,sp'] + [f'{k * sc.sample_time:g},{o:.17g},{p:.17g},{s:.17g}'
                              for k, (o, p, s) in enumerate(zip(rec['op'], pv, rec['sp']))]
    (tmp_path / 'codes.csv').write_text('\n'.join(lines) + '\n')
    record = load_record(tmp_path / 'codes.csv')
    assert not record.valid[list(codes)].any()
    assert np.isnan(record.signals['pv'][list(codes)]).all()
    assert int(np.sum(~record.valid)) == len(codes)
    reasons = {e['reason'] for e in record.excluded}
    assert reasons == {'pv beyond +-1e15, which no instrument reads (a code for a bad value, '
                       'or no measurement)'}
    # A value just under the limit is a value.
    assert abs(pv[0]) < NOT_A_MEASUREMENT
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        report = analyze(record, Options(hammerstein=False)).report
    assert report['stiction']['answer'] in ('stiction', 'no stiction', 'cannot tell')
    assert report['valid_samples'] == len(pv) - len(codes)


def _f64(x):
    return b'\x00\x01\x00\x00' + struct.pack('<d', x)


def test_a_bag_value_the_loop_nodes_reject_is_read_as_they_read_it(tmp_path):
    sc, rec = _loop()
    ts_ns = int(sc.sample_time * 1e9)
    w = BagWriter(tmp_path / 'bag', chunk_size=4096)
    for name in ('/op', '/pv', '/sp'):
        w.add_topic(name, 'std_msgs/msg/Float64', [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    absurd = {100: 1e300, 101: 2 * INPUT_LIMIT, 102: -1e7}
    for k in range(len(rec['op'])):
        w.write('/op', _f64(float(rec['op'][k])), k * ts_ns)
        w.write('/pv', _f64(absurd.get(k, float(rec['pv'][k]))), k * ts_ns + ts_ns // 4)
        w.write('/sp', _f64(float(rec['sp'][k])), k * ts_ns + ts_ns // 4)
    w.close()
    record = load_record(tmp_path / 'bag')
    assert not record.valid[list(absurd)].any() and record.valid[99] and record.valid[103]
    assert [e['reason'] for e in record.excluded] == [
        "pv beyond +-1e6, the loop nodes' input limit, which rejects it"]
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        report = analyze(record, Options(hammerstein=False)).report
    assert report['valid_samples'] == len(rec['op']) - len(absurd)
