"""
Bags the way rosbag2 writes them (a directory of MCAP files plus metadata.yaml).

Pure Python on top of ``mcap``: the recorder node writes through
:mod:`.writer`, the analyzer reads through :mod:`.reader`, and
:mod:`.repair` rebuilds the index of a bag whose recorder was killed.
"""
