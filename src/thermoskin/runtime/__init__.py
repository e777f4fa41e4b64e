"""Runtime and recording: the loop body, the loops that run it, safety, logs and recordings.

:mod:`~thermoskin.runtime.controller` is the loop body, ``SkinController.step`` (pump, MPC,
inner loop, then the estimator with the drive just applied), run in process
(:mod:`~thermoskin.runtime.closed_loop`), in a fixed-rate loop process against a device
(:mod:`~thermoskin.runtime.realtime`) or for a whole skin (:mod:`~thermoskin.runtime.skin_loop`);
:mod:`~thermoskin.runtime.supervisor` puts the skin in its safe state on a fault and
:mod:`~thermoskin.runtime.stopping` stops cleanly on a signal; :mod:`~thermoskin.runtime.runlog`
and :mod:`~thermoskin.runtime.digest` write the log and gather the run's report as it goes;
:mod:`~thermoskin.runtime.record` writes, reads (damage-tolerant, :mod:`~thermoskin.runtime.mcap_scan`),
exports and replays MCAP recordings, :mod:`~thermoskin.runtime.ros2` as ROS 2 messages.
"""
