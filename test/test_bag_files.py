"""
Bag files without ROS: schema text, writer/reader round trip, truncation, repair.

The schema format and metadata layout follow rosbag2 (Jazzy); ``rosbags``
reading our files is the independent check.
"""

import struct

import pytest
from rosbags.rosbag2 import Reader
from stiction_ros.app.live_summary import format_summary, summarise
from stiction_ros.bag.metadata import qos_profile
from stiction_ros.bag.msg_definitions import schema_text, SEPARATOR
from stiction_ros.bag.reader import BagReadError, read_bag
from stiction_ros.bag.repair import repair_bag
from stiction_ros.bag.writer import BagError, BagWriter
from stiction_ros.resources import config_file
from stiction_ros.sim.loop_config import ConfigError, load_loop
from stiction_ros.sim.ros_params import node_parameters, node_params_file, params_file
import yaml


def f64(x):
    return b'\x00\x01\x00\x00' + struct.pack('<d', x)


def write(path, n=500, chunk_size=2048):
    w = BagWriter(path, chunk_size=chunk_size)
    for name in ('/op', '/mv'):
        w.add_topic(name, 'std_msgs/msg/Float64', [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    for i in range(n):
        w.write('/op', f64(0.5 * i), i * 10**9)
        w.write('/mv', f64(-i), i * 10**9 + 1)
    w.close()
    return path


def test_a_bag_without_some_loop_topics_is_summarised_on_those_it_has(tmp_path):
    # A loop killed before the plant and the set point published: OP and MV are there.
    cfg = load_loop(config_file('concentration_loop.yaml'), 'overshoot')
    s = summarise(read_bag(write(tmp_path / 'bag', n=200)), cfg)
    assert sorted(s['signals']) == ['mv', 'op']
    assert [w.split(':')[0] for w in s['warnings']] == ['sp', 'pv']
    assert "no topic 'pv'" in format_summary(s)
    # A topic recorded without a message (its publisher never ran) is named too.
    w = BagWriter(tmp_path / 'empty', chunk_size=2048)
    for name in ('/op', '/pv'):
        w.add_topic(name, 'std_msgs/msg/Float64', [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    for i in range(200):
        w.write('/op', f64(0.5 * i), i * 10**9)
    w.close()
    s = summarise(read_bag(tmp_path / 'empty'), cfg)
    assert sorted(s['signals']) == ['op'] and 'pv: /pv has no message' in s['warnings']


def test_schema_has_every_dependency_once_after_the_rosbag2_separator():
    text = schema_text('diagnostic_msgs/msg/DiagnosticArray')
    names = [line[5:] for line in text.splitlines() if line.startswith('MSG: ')]
    assert names == ['diagnostic_msgs/DiagnosticStatus', 'diagnostic_msgs/KeyValue',
                     'std_msgs/Header', 'builtin_interfaces/Time']
    assert text.count(SEPARATOR) == 4 and len(SEPARATOR) == 80
    assert schema_text('std_msgs/msg/Float64').rstrip().endswith('float64 data')


def test_round_trip_and_independent_reader(tmp_path):
    bag = write(tmp_path / 'b')
    got = read_bag(bag)
    assert got.complete and not got.warnings
    assert list(got.topic('op').values()) == [0.5 * i for i in range(500)]
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['message_count'] == 1000 and meta['files'][0]['path'] == 'b_0.mcap'
    assert got.metadata['message_count'] == 1000      # the rosbag2 record inside the MCAP
    with Reader(bag) as reader:
        assert sorted((c.topic, c.msgcount) for c in reader.connections) == [
            ('/mv', 500), ('/op', 500)]


@pytest.mark.parametrize('keep', [0.2, 0.5, 0.9, 0.999])
def test_truncated_file_yields_its_complete_chunks_and_repairs(tmp_path, keep):
    bag = write(tmp_path / 'b')
    mcap = bag / 'b_0.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[:int(len(data) * keep)])
    got = read_bag(bag)
    assert not got.complete and 'ends early' in got.warnings[0]
    op = got.topic('op').values()
    assert list(op) == [0.5 * i for i in range(len(op))]   # a prefix, nothing invented
    assert repair_bag(bag).startswith(str(bag))
    fixed = read_bag(bag)
    assert fixed.complete and fixed.topic('op').count == len(op)
    assert 'nothing to repair' in repair_bag(bag)


def test_unreadable_inputs_are_clear_errors(tmp_path):
    with pytest.raises(BagReadError, match='no such file'):
        read_bag(tmp_path / 'missing')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagReadError, match='no .mcap file'):
        read_bag(tmp_path / 'empty')
    junk = tmp_path / 'junk.mcap'
    junk.write_bytes(b'not an mcap file at all')
    with pytest.raises(BagReadError, match='not a readable MCAP'):
        read_bag(junk)
    # Cut short before its first message: what is wrong and what to do, not an
    # exception's name.
    short = tmp_path / 'short.mcap'
    whole = write(tmp_path / 'whole')
    short.write_bytes(next(whole.glob('*.mcap')).read_bytes()[:100])
    with pytest.raises(BagReadError, match='cut short.*copy or record it again') as err:
        read_bag(short)
    assert 'EOFError' not in str(err.value)
    write(tmp_path / 'taken', n=1)
    with pytest.raises(BagError, match='not empty'):
        BagWriter(tmp_path / 'taken')


def test_loop_file_maps_to_node_parameters_and_the_shipped_params_file():
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot')
    p = node_parameters(cfg)
    assert p['valve'] == {'sample_time': 1.0, 'phase': 0.75, 'model': 'choudhury',
                          'initial_position': 50.0, 'S': 5.0, 'J': 2.0}
    assert p['controller']['Kc'] == 0.2 and p['plant']['delay'] == 10.0
    # The profile as typed parameters, its steps one flat [t0, v0, t1, v1] list.
    assert p['controller']['setpoint_profile.steps'] == [0.0, 0.0, 10.0, 1.0]
    assert p['controller']['setpoint_profile.type'] == 'steps'
    assert 'disturbance_steps' not in p['plant']     # none: the node's default, []
    # The loop launcher's file: every node by its full name, dotted names nested.
    doc = yaml.safe_load(params_file(cfg, '/loop2'))
    assert list(doc) == ['/loop2/plant', '/loop2/controller', '/loop2/valve']
    assert doc['/loop2/controller']['ros__parameters']['setpoint_profile'] == {
        'steps': [0.0, 0.0, 10.0, 1.0], 'type': 'steps'}
    shipped = config_file('params/concentration_undershoot/valve.params.yaml').read_text()
    assert shipped == node_params_file(cfg, 'valve'), 'regenerate with make params'
    noisy = load_loop(config_file('concentration_loop.yaml'), 'undershoot', {'noise.mv_std': 0.1})
    with pytest.raises(ConfigError, match='mv_std'):
        node_parameters(noisy)


def test_a_topic_whose_schema_is_not_ros2msg_is_a_clear_error(tmp_path):
    # An MCAP from another tool may carry JSON-schema or IDL types, which mcap_ros2
    # cannot decode; asking for their values names the encoding, not a TypeError.
    from mcap.writer import Writer
    path = tmp_path / 'json.mcap'
    with open(path, 'wb') as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema(name='Reading', encoding='jsonschema', data=b'{}')
        cid = w.register_channel(topic='/reading', message_encoding='cdr', schema_id=sid)
        w.add_message(channel_id=cid, log_time=1, publish_time=1, data=b'\x00\x01\x00\x00')
        w.finish()
    topic = read_bag(path).topic('/reading')
    with pytest.raises(BagReadError, match="'jsonschema'.*only ros2msg"):
        topic.values()


def test_the_summary_says_where_a_recording_left_its_offline_twin(tmp_path):
    # A recording of the offline run itself, but for OP at one sample: the summary must say
    # when the live run departed (the clue to why), not only by how much.
    from stiction_ros.sim.closed_loop import simulate_loop
    from stiction_ros.sim.ros_params import PHASES
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot')
    off = simulate_loop(cfg, duration=60.0)
    op = off['op'][:61].copy()
    op[37] += 0.066
    w = BagWriter(tmp_path / 'bag', chunk_size=2048)
    for name in ('/op', '/mv'):
        w.add_topic(name, 'std_msgs/msg/Float64', [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    for k in range(61):
        for name, value in (('/op', op[k]), ('/mv', off['mv'][k])):
            phase = PHASES['controller' if name == '/op' else 'valve']
            w.write(name, f64(float(value)), int(round((k + phase) * 1e9)))
    w.close()
    s = summarise(read_bag(tmp_path / 'bag'), cfg)
    assert s['signals']['mv']['first_difference_s'] is None
    assert s['signals']['mv']['max_abs_difference'] == 0.0
    assert s['signals']['op']['first_difference_s'] == 37.0
    assert abs(s['signals']['op']['max_abs_difference'] - 0.066) < 1e-12
    assert 'first difference from the offline run: op at 37 s' in format_summary(s)


def test_a_split_bag_without_its_metadata_is_read_in_the_order_rosbag2_numbered_it(tmp_path):
    bag = write(tmp_path / 'b')
    (mcap,) = bag.glob('*.mcap')
    (bag / 'metadata.yaml').unlink()
    # x_2 sorts after x_10 as text; rosbag2 wrote it first.
    for name in ('b_10.mcap', 'b_2.mcap'):
        (bag / name).write_bytes(mcap.read_bytes())
    mcap.unlink()
    from stiction_ros.bag.files import mcap_files
    assert [f.name for f in mcap_files(bag)] == ['b_2.mcap', 'b_10.mcap']


def test_metadata_that_is_no_text_is_read_past(tmp_path):
    bag = write(tmp_path / 'b')
    (bag / 'metadata.yaml').write_bytes(b'\xff\xfe\x00')
    assert read_bag(bag).topic('op').count > 0


def test_a_second_repair_keeps_the_first_original(tmp_path):
    bag = write(tmp_path / 'b')
    mcap = bag / 'b_0.mcap'
    whole = mcap.read_bytes()
    mcap.write_bytes(whole[:len(whole) // 2])
    repair_bag(bag)
    first = (bag / 'b_0.mcap.damaged').read_bytes()
    mcap.write_bytes(mcap.read_bytes()[:len(mcap.read_bytes()) // 2])
    repair_bag(bag)
    assert (bag / 'b_0.mcap.damaged').read_bytes() == first
    assert (bag / 'b_0.mcap.damaged2').is_file()


def test_a_damaged_chunk_makes_the_bag_incomplete_and_names_what_is_lost(tmp_path):
    bag = write(tmp_path / 'b')
    mcap = bag / 'b_0.mcap'
    data = bytearray(mcap.read_bytes())

    def count(b):
        return sum(t.count for t in b.topics.values())
    whole = count(read_bag(bag))
    at = int(len(data) * 0.4)     # inside a chunk (zstd): its messages cannot be read
    data[at:at + 200] = bytes(200)
    mcap.write_bytes(bytes(data))
    got = read_bag(bag)
    assert count(got) < whole
    # It had read as complete, and "nothing to repair", with a chunk's messages gone.
    assert not got.complete
    lost = [w for w in got.warnings if 'is damaged' in w]
    assert lost and 'messages are lost' in lost[0]
    assert 'recovered' in repair_bag(bag)
    assert read_bag(bag).complete and count(read_bag(bag)) == count(got)
