"""
ROS 2 message definitions as rosbag2 stores them in MCAP schemas (``ros2msg``).

rosbag2 stores the ``.msg`` text of a type followed by the text of every type
it depends on, each after a line of 80 ``=`` and ``MSG: pkg/msg/Type``, so a
reader can decode the messages without the packages installed.  The ``.msg``
files come from the ``share/`` directories of the installed interface
packages (a sourced ROS install, or the ``ros-jazzy-*`` wheels in the venv).
"""

import os
from pathlib import Path
import re
import sys

from stiction_ros.errors import DefinitionNotFound

SEPARATOR = '=' * 80
PRIMITIVES = {
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring',
}
_FIELD = re.compile(r'^\s*([A-Za-z0-9_/]+)(?:<=\d+)?(?:\[[^\]]*\])?\s+[A-Za-z0-9_]+')


def share_dirs() -> list[Path]:
    """Return the ``share`` directories to search: AMENT_PREFIX_PATH, then the venv's."""
    out = [Path(p) / 'share' for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
           if p]
    out.append(Path(sys.prefix) / 'share')
    return out


def msg_text(type_name: str) -> str:
    """Return the ``.msg`` text of ``pkg/msg/Type`` (``pkg/Type`` is accepted too)."""
    pkg, name = _split(type_name)
    for share in share_dirs():
        path = share / pkg / 'msg' / f'{name}.msg'
        if path.is_file():
            return path.read_text(encoding='utf-8')
    raise DefinitionNotFound(
        f'no definition for {pkg}/msg/{name}: {name}.msg is not under '
        + ', '.join(str(s / pkg / 'msg') for s in share_dirs()))


def _split(type_name: str) -> tuple[str, str]:
    parts = type_name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise DefinitionNotFound(f'{type_name!r} is not a message type name like std_msgs/msg/Float64')


def dependencies(type_name: str, text: str) -> list[str]:
    """Return the non-primitive field types of ``text`` as ``pkg/Type``, sorted."""
    pkg, _ = _split(type_name)
    deps = set()
    for line in text.splitlines():
        m = _FIELD.match(line.split('#', 1)[0])
        if not m or m.group(1) in PRIMITIVES:
            continue
        ftype = m.group(1)
        if ftype == 'Header':
            deps.add('std_msgs/Header')
        elif '/' in ftype:
            deps.add('/'.join(_split(ftype)))
        else:
            deps.add(f'{pkg}/{ftype}')
    return sorted(deps)


def schema_text(type_name: str) -> str:
    """
    Return the ``ros2msg`` schema text of a type: its ``.msg`` then every dependency.

    As rosbag2 does: depth first, dependencies of each type in sorted order,
    each type once, named as ``pkg/Type`` after ``MSG:``.
    """
    seen = set()

    def walk(name: str) -> str:
        text = msg_text(name)
        out = [text]
        for dep in dependencies(name, text):
            if dep in seen:
                continue
            seen.add(dep)
            out.append(f'\n{SEPARATOR}\nMSG: {dep}\n')
            out.append(walk(dep))
        return ''.join(out)

    pkg, name = _split(type_name)
    seen.add(f'{pkg}/{name}')
    return walk(type_name)
