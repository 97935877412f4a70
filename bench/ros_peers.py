"""
Helper processes of the live benchmarks (``python -m bench.ros_peers MODE ...``).

- ``echo``: republishes every Float64 on ``ping`` to ``pong`` (the round-trip peer).
- ``ping N``: sends N pings one at a time, waits for each pong, prints the
  round-trip times in µs, one per line.
- ``flood RATE SECONDS``: publishes RATE messages/s for SECONDS, mixed: four
  Float64 topics carrying their sequence number and one String topic; prints
  the count sent per topic as JSON at the end.

The caller sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ``ROS_DOMAIN_ID``.
"""

import json
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, String

QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                 reliability=ReliabilityPolicy.RELIABLE)
# The flood keeps a second of messages for a slow reader: reliable delivery then loses
# nothing unless the reader falls a whole second behind.
FLOOD_QOS = QoSProfile(depth=20000, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE)
FLOAT_TOPICS = ('/flood/a', '/flood/b', '/flood/c', '/flood/d')
TEXT_TOPIC = '/flood/text'


def echo():
    """Republish ping on pong until SIGINT."""
    node = Node('bench_echo')
    pub = node.create_publisher(Float64, 'pong', QOS)
    node.create_subscription(Float64, 'ping', pub.publish, QOS)
    rclpy.spin(node)


def ping(n):
    """Measure ``n`` round trips; print them in µs."""
    node = Node('bench_ping')
    pub = node.create_publisher(Float64, 'ping', QOS)
    got = []
    node.create_subscription(Float64, 'pong', lambda m: got.append(m.data), QOS)
    deadline = time.monotonic() + 30.0
    while pub.get_subscription_count() == 0 or node.count_publishers('pong') == 0:
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() > deadline:
            sys.exit('ping: no echo peer found')
    msg = Float64()
    rtts = []
    for i in range(n + 50):
        msg.data = float(i)
        t0 = time.perf_counter_ns()
        pub.publish(msg)
        while not got or got[-1] != float(i):
            rclpy.spin_once(node, timeout_sec=1.0)
        if i >= 50:  # the first ones warm the path up
            rtts.append((time.perf_counter_ns() - t0) / 1000.0)
    print('\n'.join(f'{r:.1f}' for r in rtts))


def flood(rate, seconds):
    """Publish ``rate`` messages/s over five topics for ``seconds``; print counts."""
    node = Node('bench_flood')
    pubs = [node.create_publisher(Float64, t, FLOOD_QOS) for t in FLOAT_TOPICS]
    text = node.create_publisher(String, TEXT_TOPIC, FLOOD_QOS)
    # Wait for the recorder to subscribe to every topic.
    deadline = time.monotonic() + 30.0
    while any(p.get_subscription_count() == 0 for p in pubs + [text]):
        time.sleep(0.05)
        if time.monotonic() > deadline:
            sys.exit('flood: the recorder did not subscribe')
    time.sleep(0.5)
    counts = dict.fromkeys(FLOAT_TOPICS + (TEXT_TOPIC,), 0)
    fmsg, smsg = Float64(), String()
    batch = max(1, int(rate * 0.005))
    t0 = time.monotonic()
    sent = 0
    total = int(rate * seconds)
    while sent < total:
        # Catch up to the schedule in batches of 5 ms worth of messages.
        due = min(total, int((time.monotonic() - t0) * rate) + batch)
        while sent < due:
            slot = sent % 10
            if slot == 9:
                smsg.data = f'message {sent}: status text of a typical length'
                text.publish(smsg)
                counts[TEXT_TOPIC] += 1
            else:
                topic = FLOAT_TOPICS[slot % 4]
                fmsg.data = float(counts[topic])
                pubs[slot % 4].publish(fmsg)
                counts[topic] += 1
            sent += 1
        time.sleep(0.001)
    elapsed = time.monotonic() - t0
    time.sleep(1.0)
    print(json.dumps({'counts': counts, 'seconds': elapsed}))


def main(argv):
    """Run one mode."""
    rclpy.init()
    try:
        if argv[0] == 'echo':
            echo()
        elif argv[0] == 'ping':
            ping(int(argv[1]))
        else:
            flood(float(argv[1]), float(argv[2]))
    except KeyboardInterrupt:
        pass
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    main(sys.argv[1:])
