"""Laws that set c2 every sample in the damper path, and their compiled loops (no ROS).

A per-sample law runs where a real semi-active damper runs it, in the damper's own controller,
far faster than the graph's blocks; a supervising node only arms it
(:mod:`aero_dva.control.controllers`). Here, the law and the machinery that flies it:

- :mod:`.switching_law`: the per-sample law ``F h > 0`` and the signals it measures; the
  switching law holds one row ``h``, the clipped-optimal law of Dyke et al. (1996)
  (:mod:`aero_dva.control.clipped_optimal`) one per airspeed of its schedule;
- :mod:`.flight`: a whole flight (or a batch of seeds) with the law armed;
- :mod:`.stream`: the law in the simulator's damper path, block by block;
- :mod:`.kernel`: the compiled per-sample loop both run (numba);
- :mod:`.smooth_tables`: the loop's per-sample maps, interpolated over airspeed and c2;
- :mod:`.replay`: a flight flown again with the c2 a law recorded, sample by sample.
"""
