"""Fault trials of ``bench/bench_faults.py``, shared with the tests that assert the invariants.

- :mod:`bench.faults.cli_matrix`: malformed inputs to every ``dva`` command that reads a file
  (the files themselves: :mod:`bench.faults.bad_inputs`);
- :mod:`bench.faults.ros_processes`: nodes started as processes (as ``ros2 run`` would) and an
  in-process probe node that logs what the graph publishes;
- :mod:`bench.faults.recorder_faults`: the recorder killed by SIGINT, SIGTERM or SIGKILL at a
  random moment of a flight, messages lost counted against the simulator's sample indexes;
- :mod:`bench.faults.bag_recovery`: the one step that recovers a bag after SIGKILL;
- :mod:`bench.faults.controller_faults`: the controller process killed mid-flight;
- :mod:`bench.faults.command_faults`: command bursts at 10 kHz and invalid commands.
"""
