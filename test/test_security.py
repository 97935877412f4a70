"""
Nothing read from a file can make the package run code.

A scan of the package's syntax trees finds no way in (no eval/exec, no pickle or
marshal, no YAML loader but the safe one, no shell=True), and files that try the
usual ways (a YAML python tag, a pickled array) are refused without running them.
"""

import ast
from pathlib import Path

import numpy as np
import pytest

from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.record import InputError
from stiction_ros.bag.reader import read_bag
from stiction_ros.bag.writer import BagWriter
from stiction_ros.sim.loop_config import ConfigError, load_loop

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted((ROOT / 'stiction_ros').rglob('*.py')) + sorted((ROOT / 'launch').glob('*.py'))
BANNED_CALLS = {'eval', 'exec', 'compile', 'input'}
BANNED_MODULES = {'pickle', 'cPickle', 'marshal', 'shelve', 'dill', 'cloudpickle', 'joblib'}
UNSAFE_YAML = {'load', 'load_all', 'unsafe_load', 'unsafe_load_all', 'full_load',
               'full_load_all', 'Loader', 'UnsafeLoader', 'FullLoader'}
# The one dynamic import: a message type named by the ROS graph, checked against
# pkg/msg/Type first (recorder_node._import_type).
ALLOWED_IMPORT = ('recorder_node.py', '_import_type')


def _offences(path):
    tree = ast.parse(path.read_text(encoding='utf-8'), str(path))
    parents = {}
    for node in ast.walk(tree):
        for child in ast.iter_child_nodes(node):
            parents[child] = node
    out = []
    for node in ast.walk(tree):
        where = f'{path.relative_to(ROOT)}:{getattr(node, "lineno", 0)}'
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names]
            if isinstance(node, ast.ImportFrom) and node.module:
                names.append(node.module)
            out += [f'{where} imports {n}' for n in names if n.split('.')[0] in BANNED_MODULES]
        elif isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Name) and f.id in BANNED_CALLS:
                out.append(f'{where} calls {f.id}()')
            if isinstance(f, ast.Name) and f.id == '__import__':
                func = node
                while func is not None and not isinstance(func, ast.FunctionDef):
                    func = parents.get(func)
                if (path.name, getattr(func, 'name', None)) != ALLOWED_IMPORT:
                    out.append(f'{where} calls __import__()')
            if (isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name)
                    and f.value.id == 'yaml' and f.attr in UNSAFE_YAML):
                out.append(f'{where} calls yaml.{f.attr}()')
            for kw in node.keywords:
                if (kw.arg in ('shell', 'allow_pickle') and isinstance(kw.value, ast.Constant)
                        and kw.value.value is True):
                    out.append(f'{where} passes {kw.arg}=True')
        elif isinstance(node, ast.Attribute) and node.attr in ('UnsafeLoader', 'FullLoader'):
            out.append(f'{where} uses yaml.{node.attr}')
    return out


def test_no_source_file_can_run_code_from_its_input():
    offences = [o for path in SOURCES for o in _offences(path)]
    assert not offences, offences
    assert len(SOURCES) > 50


def test_the_scan_finds_what_it_looks_for(tmp_path):
    bad = tmp_path / 'bad.py'
    bad.write_text('import pickle\nimport yaml\n'
                   'def f(s):\n    eval(s)\n    yaml.load(s)\n    __import__(s)\n'
                   '    subprocess.run(s, shell=True)\n    np.load(s, allow_pickle=True)\n')
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        found = _offences(bad)
    finally:
        ROOT = saved
    assert len(found) == 6, found


PYTHON_TAG = "!!python/object/apply:os.system ['touch {}']"


def test_a_loop_file_with_a_python_tag_is_refused_unrun(tmp_path):
    flag = tmp_path / 'ran'
    cfg = tmp_path / 'loop.yaml'
    cfg.write_text(f'name: x\nsample_time: {PYTHON_TAG.format(flag)}\n', encoding='utf-8')
    with pytest.raises(ConfigError):
        load_loop(cfg)
    assert not flag.exists()


def test_bag_metadata_with_a_python_tag_is_ignored_unrun(tmp_path):
    flag = tmp_path / 'ran'
    w = BagWriter(tmp_path / 'bag')
    w.add_topic('/op', 'std_msgs/msg/Float64', [])
    w.write('/op', b'\x00\x01\x00\x00' + np.float64(1.5).tobytes(), 10**9)
    w.close()
    meta = tmp_path / 'bag' / 'metadata.yaml'
    meta.write_text(f'rosbag2_bagfile_information: {PYTHON_TAG.format(flag)}\n')
    bag = read_bag(tmp_path / 'bag')
    assert bag.topics['/op'].values().tolist() == [1.5]
    assert not flag.exists()


def test_a_pickled_array_is_not_a_recording(tmp_path):
    path = tmp_path / 'loop.npy'
    np.save(path, np.array([{'op': 1}], dtype=object), allow_pickle=True)
    with pytest.raises(InputError):
        load_record(path)
