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


def _cdr_string(text, at):
    raw = text.encode() + b'\0'
    pad = b'\0' * (-at % 4)
    return pad + struct.pack('<I', len(raw)) + raw


def _key_value(key, value):
    # diagnostic_msgs/KeyValue in CDR: two strings, the second aligned to 4 bytes.
    first = _cdr_string(key, 0)
    return b'\x00\x01\x00\x00' + first + _cdr_string(value, len(first))


def test_a_bag_value_the_loop_nodes_reject_is_read_as_they_read_it(tmp_path):
    sc, rec = _loop()
    ts_ns = int(sc.sample_time * 1e9)
    w = BagWriter(tmp_path / 'bag', chunk_size=4096)
    for name in ('/op', '/mv', '/pv', '/sp'):
        w.add_topic(name, 'std_msgs/msg/Float64', [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    w.add_topic('/held_inputs', 'diagnostic_msgs/msg/KeyValue', [qos_profile(depth=100)],
                'RIHS01_' + '0' * 64)
    # OP and MV in % of span beyond the nodes' limit; a PV of 2e6 (a pressure in Pa) is a
    # value, one of 1e300 is not.  At sample 50 the plant rejected the MV of 1e9 and acted
    # on the one before: a held sample, which the valve fits would otherwise keep.
    bad_op, bad_mv, big_pv, no_pv = {100: 1e9}, {50: -2 * INPUT_LIMIT}, {120: 2e6}, {130: 1e300}
    for k in range(len(rec['op'])):
        t0 = 10**9 + k * ts_ns
        w.write('/pv', _f64(no_pv.get(k, big_pv.get(k, float(rec['pv'][k])))), t0 + ts_ns // 4)
        w.write('/op', _f64(bad_op.get(k, float(rec['op'][k]))), t0 + ts_ns // 2)
        w.write('/sp', _f64(float(rec['sp'][k])), t0 + ts_ns // 2)
        w.write('/mv', _f64(bad_mv.get(k, float(rec['mv'][k]))), t0 + 3 * ts_ns // 4)
        if k == 50:
            # The node's own sample number: samples since its clock's zero.
            mark = f'{round(t0 / ts_ns)} {float(rec["mv"][49])!r}'
            w.write('/held_inputs', _key_value('/mv', mark), t0 + ts_ns // 4)
    w.close()
    record = load_record(tmp_path / 'bag')
    reasons = {}
    for e in record.excluded:
        for reason in e['reason'].split('; '):
            reasons[reason] = reasons.get(reason, 0) + e['samples']
    assert reasons["op, mv beyond +-1e6 % of span, which the loop's nodes reject (their "
                   'input_limit)'] == 2
    assert reasons['pv beyond +-1e15, which no instrument reads (a code for a bad value, '
                   'or no measurement)'] == 1
    assert record.signals['pv'][120] == 2e6 and record.valid[120]
    assert not record.valid[[50, 100, 130]].any()
    # The valve fits never read the absurd MV, held sample or not.
    assert all(not a <= 50 < b for a, b in record.valve_segments())
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        report = analyze(record, Options(hammerstein=False)).report
    assert all(np.isfinite(f['mse']) for f in report['fits'])
