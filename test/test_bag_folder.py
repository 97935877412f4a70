"""A bag folder whose metadata.yaml disagrees with its files: nothing lost, each thing said."""

import struct

import pytest
from stiction_ros.bag.files import bag_files
from stiction_ros.bag.metadata import qos_profile
from stiction_ros.bag.reader import BagReadError, read_bag
from stiction_ros.bag.repair import repair_bag
from stiction_ros.bag.writer import BagWriter
import yaml


def f64(x):
    return b'\x00\x01\x00\x00' + struct.pack('<d', x)


def write(path, n=200, start=0):
    w = BagWriter(path, chunk_size=2048)
    w.add_topic('/op', 'std_msgs/msg/Float64', [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    for i in range(start, start + n):
        w.write('/op', f64(0.5 * i), i * 10**9)
    w.close()
    return path


@pytest.mark.parametrize('text, why', [
    ('hello: 1\n', 'not rosbag2 metadata'),
    ('[1, 2\n', 'not valid YAML'),
    ('rosbag2_bagfile_information: {relative_file_paths: [3]}\n', 'not rosbag2 metadata'),
])
def test_metadata_that_is_no_rosbag2_metadata_is_read_past_and_said(tmp_path, text, why):
    bag = write(tmp_path / 'b')
    (bag / 'metadata.yaml').write_text(text)
    got = read_bag(bag)
    assert got.topic('op').count == 200 and got.complete
    assert any(w.startswith(f'metadata.yaml is {why}') for w in got.warnings)
    # A repair writes it again, and then the bag reads clean.
    assert 'recovered 200 messages' in repair_bag(bag)
    again = read_bag(bag)
    assert again.complete and not again.warnings and again.topic('op').count == 200


def _also_named(bag, name):
    # metadata.yaml names one file more than the folder holds.
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    meta['rosbag2_bagfile_information']['relative_file_paths'].append(name)
    (bag / 'metadata.yaml').write_text(yaml.safe_dump(meta))
    return bag


def test_a_file_metadata_names_and_the_folder_lacks_makes_the_bag_incomplete(tmp_path):
    bag = _also_named(write(tmp_path / 'b'), 'b_1.mcap')
    got = read_bag(bag)
    assert not got.complete and got.topic('op').count == 200
    assert any('names b_1.mcap, not in the bag' in w for w in got.warnings)


def test_a_file_the_metadata_leaves_out_is_read_too(tmp_path):
    bag = write(tmp_path / 'b')
    later = write(tmp_path / 'later', start=200)
    (later / 'later_0.mcap').rename(bag / 'b_1.mcap')
    got = read_bag(bag)
    # Both files' messages, in time order, the unnamed one said.
    assert list(got.topic('op').values()) == [0.5 * i for i in range(400)]
    assert any(w.startswith('b_1.mcap in the folder, not named') for w in got.warnings)
    assert [f.name for f in bag_files(bag).files] == ['b_0.mcap', 'b_1.mcap']


def test_metadata_naming_a_file_outside_the_bag_is_not_followed(tmp_path):
    bag = write(tmp_path / 'b')
    write(tmp_path / 'other', start=1000)
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    meta['rosbag2_bagfile_information']['relative_file_paths'] = ['../other/other_0.mcap']
    (bag / 'metadata.yaml').write_text(yaml.safe_dump(meta))
    got = read_bag(bag)
    assert list(got.topic('op').values()) == [0.5 * i for i in range(200)]
    assert any("'../other/other_0.mcap', outside the bag" in w for w in got.warnings)


def test_a_folder_with_metadata_and_no_mcap_file_is_an_error(tmp_path):
    bag = write(tmp_path / 'b')
    (bag / 'b_0.mcap').unlink()
    with pytest.raises(BagReadError, match='no .mcap file in this directory'):
        read_bag(bag)


def test_repair_of_a_path_that_does_not_exist_says_so(tmp_path):
    with pytest.raises(BagReadError, match='no such file or directory'):
        repair_bag(tmp_path / 'nothing')


def test_a_hidden_copy_beside_the_file_is_not_read(tmp_path):
    bag = write(tmp_path / 'b')
    (bag / '._b_0.mcap').write_bytes(b'\x00\x05\x16\x07Mac OS X        ')
    got = read_bag(bag)
    assert got.complete and not got.warnings and got.topic('op').count == 200


def test_a_bags_file_may_be_a_link_into_a_store(tmp_path):
    bag = write(tmp_path / 'b')
    store = tmp_path / 'store'
    store.mkdir()
    (bag / 'b_0.mcap').rename(store / 'blob')
    (bag / 'b_0.mcap').symlink_to(store / 'blob')
    got = read_bag(bag)
    assert got.complete and not got.warnings and got.topic('op').count == 200


def test_a_repair_says_what_metadata_named_and_the_folder_lacked(tmp_path):
    said = repair_bag(_also_named(write(tmp_path / 'b'), 'b_1.mcap'))
    assert 'names b_1.mcap, not in the bag' in said and 'only the files present' in said
