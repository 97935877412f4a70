"""
The bag's ``metadata.yaml`` (rosbag2_bagfile_information, version 9) and QoS YAML.

Version 9 writes QoS policies as names (``reliable``, ``keep_last``); the
MCAP channel metadata holds the same profile list as a YAML string, and the
``rosbag2`` metadata record inside the MCAP holds the bag metadata without
the outer ``rosbag2_bagfile_information`` key, as rosbag2_storage_mcap does.
"""

import os
from typing import Any, Iterable

import yaml

VERSION = 9
# Infinite durations as rmw writes them (RMW_DURATION_INFINITE in sec/nsec).
INFINITE = {'sec': 9223372036, 'nsec': 854775807}


def qos_profile(reliability: str = 'reliable', durability: str = 'volatile',
                history: str = 'keep_last', depth: int = 10) -> dict[str, Any]:
    """Return one offered QoS profile as rosbag2 version 9 stores it."""
    return {
        'history': history, 'depth': int(depth), 'reliability': reliability,
        'durability': durability, 'deadline': dict(INFINITE), 'lifespan': dict(INFINITE),
        'liveliness': 'automatic', 'liveliness_lease_duration': dict(INFINITE),
        'avoid_ros_namespace_conventions': False,
    }


def qos_yaml(profiles: Iterable[dict[str, Any]]) -> str:
    """Return the channel-metadata form of a list of QoS profiles (a YAML string)."""
    return yaml.safe_dump(list(profiles), sort_keys=False, default_flow_style=False).rstrip('\n')


def bag_metadata(file_name: str, topics: list[dict[str, Any]], start_ns: int, end_ns: int,
                 ros_distro: str | None = None) -> dict[str, Any]:
    """
    Return the bag metadata mapping (the content under rosbag2_bagfile_information).

    ``topics`` is a list of dicts with ``name``, ``type``, ``qos`` (list of
    profiles), ``type_hash`` and ``count``.
    """
    total = sum(t['count'] for t in topics)
    duration = max(end_ns - start_ns, 0) if total else 0
    start = start_ns if total else 0
    return {
        'version': VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': int(duration)},
        'starting_time': {'nanoseconds_since_epoch': int(start)},
        'message_count': int(total),
        'topics_with_message_count': [{
            'topic_metadata': {
                'name': t['name'], 'type': t['type'], 'serialization_format': 'cdr',
                'offered_qos_profiles': list(t['qos']),
                'type_description_hash': t.get('type_hash', ''),
            },
            'message_count': int(t['count']),
        } for t in topics],
        # Compression is inside the MCAP chunks, not rosbag2 file compression.
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [{
            'path': file_name,
            'starting_time': {'nanoseconds_since_epoch': int(start)},
            'duration': {'nanoseconds': int(duration)},
            'message_count': int(total),
        }],
        'custom_data': {'writer': 'stiction_ros'},
        'ros_distro': ros_distro or os.environ.get('ROS_DISTRO', 'jazzy'),
    }


def metadata_yaml(meta: dict[str, Any]) -> str:
    """Return the text of ``metadata.yaml`` for a bag metadata mapping."""
    return yaml.safe_dump({'rosbag2_bagfile_information': meta}, sort_keys=False)


def serialized_metadata(meta: dict[str, Any]) -> str:
    """Return the text of the ``rosbag2`` MCAP metadata record for a bag metadata mapping."""
    return yaml.safe_dump(meta, sort_keys=False)
