"""
analyzer node: analyse one recording, write the report, publish the verdict once.

    ros2 run stiction_ros analyzer --ros-args -p input:=out/demo_bag -p report:=report.json

The verdict goes to ``diagnostics`` (``/diagnostics``, or ``/ns/diagnostics``
in a namespace) as one ``diagnostic_msgs/DiagnosticArray``
(reliable, transient local, so a monitor started a little later still gets
it): level OK (no stiction), WARN (stiction, or the data are inconclusive),
ERROR (stiction with apparent S of at least ``error_S`` %, or an input that
cannot be analysed), with S, J, MSE and the score as key values.  The node
stays up ``linger`` seconds for late subscribers, then exits: 0 when the
analysis ran, 2 when the input could not be analysed.
"""

import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from stiction_ros.analysis.detection import BAND, probability_text
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
from stiction_ros.errors import InputError, StictionError
from stiction_ros.nodes.params import declare, Param
from stiction_ros.nodes.run import run

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def level_of(report, error_s):
    """Return (level, message) of the diagnostic for a report."""
    st = report['stiction']
    sizes = [f['S'] for f in report['fits']] or [st.get('apparent_S') or 0.0]
    if st['detected'] is None:
        return DiagnosticStatus.WARN, 'cannot tell: ' + st.get('reason', '')
    if not st['detected']:
        play = st.get('play')
        if play is None:
            return DiagnosticStatus.OK, 'no stiction detected'
        # Play is no stick-slip, but a band this wide still makes a loop hunt.
        level = DiagnosticStatus.WARN if play >= error_s else DiagnosticStatus.OK
        return level, (f'no stiction detected; play of {play:.2f} % without a slip jump '
                       '(a deadband or backlash)')
    size = max(s for s in sizes if s is not None)
    level = DiagnosticStatus.ERROR if size >= error_s else DiagnosticStatus.WARN
    if st.get('probability') is not None:
        shown = probability_text(st['probability'], BAND)
        return level, (f'stiction detected (probability {shown}'
                       + (f', S about {size:.2f} %)' if size else ')'))
    return level, f'stiction detected (score {st["score"]:.2f}, S about {size:.2f} %)'


def key_values(report):
    """Return the key values of the diagnostic: score, S, J and MSE per fitted model."""
    st = report['stiction']
    kv = [('detected', st['detected']), ('answer', st.get('answer')),
          ('probability', st.get('probability')), ('score', f'{st["score"]:.3f}'),
          ('apparent_S', st.get('apparent_S')), ('play', st.get('play')),
          ('samples', report['samples'])]
    if st.get('size_caution'):
        kv.append(('size_caution', st['size_caution']))
    for f in report['fits']:
        kv += [(f'{f["model"]}.S', f'{f["S"]:.2f}'), (f'{f["model"]}.J', f'{f["J"]:.2f}'),
               (f'{f["model"]}.mse', f'{f["mse"]:.5g}')]
    # A figure the analysis has not (no detector probability where MV decided, no size)
    # is left out, not written 'None'; detected stays, as 'None' for cannot tell.
    return [KeyValue(key=k, value=str(v)) for k, v in kv if v is not None or k == 'detected']


class AnalyzerNode(Node):
    """Runs the offline analyzer once on its ``input`` and publishes the verdict."""

    PARAMS = [
        Param('input', '', 'Recording to analyse: bag directory, .mcap, CSV or historian file.',
              read_only=True),
        Param('report', '', 'Where to write the JSON report ("" = do not write).',
              read_only=True),
        Param('html', '', 'Where to write the HTML report ("" = do not write).', read_only=True),
        Param('model', 'both', 'Model(s) to fit when MV is present.',
              choices=('kano', 'choudhury', 'both'), read_only=True),
        Param('S', -1.0, 'Given S in % (negative: identify S and J).', -1.0, 100.0,
              read_only=True),
        Param('J', -1.0, 'Given J in % (used when S is given).', -1.0, 100.0, read_only=True),
        Param('topic_namespace', '', 'Namespace of the loop topics inside the bag.',
              read_only=True),
        Param('loop_type', 'auto', 'Loop type for the signatures.',
              choices=('auto', 'self-regulating', 'integrating'), read_only=True),
        Param('error_S', 2.0, 'Stiction at least this large (%) is reported as ERROR.',
              0.0, 100.0, read_only=True),
        Param('linger', 3.0, 'Seconds to stay up after publishing, for late subscribers.',
              0.0, 3600.0, read_only=True),
    ]

    @classmethod
    def declared_params(cls) -> list:
        """Return every parameter the analyzer node declares (``--help`` lists them)."""
        return list(cls.PARAMS)

    def __init__(self):
        super().__init__('analyzer')
        self.values = declare(self, self.PARAMS)
        # Relative, as the loop nodes': /diagnostics unless run in a loop's namespace.
        self.pub = self.create_publisher(DiagnosticArray, 'diagnostics', LATCHED)
        self.finished = Future()
        self.code = self._analyse()
        self.create_timer(max(self.values['linger'], 0.01), self._done)

    def _analyse(self):
        v = self.values
        status = DiagnosticStatus(name=f'stiction_ros analyzer: {v["input"]}',
                                  hardware_id=v['input'])
        try:
            report = self._report()
        except (StictionError, ValueError, OSError) as exc:
            self.get_logger().error(f'cannot analyse {v["input"]!r}: {exc}')
            status.level, status.message = DiagnosticStatus.ERROR, f'cannot analyse: {exc}'
            code = 2
        else:
            status.level, status.message = level_of(report, v['error_S'])
            status.values = key_values(report)
            self.get_logger().info(status.message)
            # Damage to the recording itself (a bag cut short): read from what was readable.
            for warning in report['input'].get('warnings') or []:
                self.get_logger().warning(warning)
            code = 0
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub.publish(msg)
        return code

    def _report(self):
        v = self.values
        if not v['input']:
            raise InputError('parameter input is empty: give -p input:=PATH')
        # Negative S and J are the parameters' way of saying "identify them".
        options = AnalyzeOptions(
            input=v['input'], model=v['model'], S=v['S'] if v['S'] >= 0.0 else None,
            J=v['J'] if v['J'] >= 0.0 else None, namespace=v['topic_namespace'] or None,
            loop_type=v['loop_type'], json_path=v['report'] or None, html_path=v['html'] or None)
        return analyze_file(options, self.get_logger().info).report

    def _done(self):
        if not self.finished.done():
            self.finished.set_result(self.code)


def main(args=None):
    """Run the analyzer once and exit."""
    return run(AnalyzerNode, args, 'analyzer')


if __name__ == '__main__':
    sys.exit(main())
