"""The oracle of the batch recorder: the simulator's messages built as ``rosbags`` messages,
serialized by rosbags' typestore and written one by one with ``BagWriter`` (mcap's writer).

Field values follow the simulator node (``dva_ros_common.conversions``): header stamps at the
block's first sample (``t0``) for the sample blocks and the flight condition, ``t_end`` for
``/clock``, the snapshot time for the damper state; frame "wing" on the acceleration and
displacement blocks; log time of every message of a block = ``t_end``.
"""
from __future__ import annotations

from aero_dva.bag import channels as ch
from aero_dva.bag.schemas import typestore
from aero_dva.bag.writer import BagWriter, qos_profile_yaml

STORE = typestore()
T = STORE.types


def ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def time_msg(seconds: float):
    sec, nanosec = divmod(ns(seconds), 1_000_000_000)
    return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def header(seconds: float, frame: str = ""):
    return T["std_msgs/msg/Header"](stamp=time_msg(seconds), frame_id=frame)


def block_messages(block, state, rate: float, displacement: bool = True) -> list:
    """(channel, rosbags message) of one block, in the node's publish order."""
    common = {"sample_rate": float(rate), "first_sample_index": int(block.first_index)}
    a, d = block.accelerations, block.displacements
    out = [
        (ch.CLOCK, T[ch.CLOCK.type_name](clock=time_msg(block.t_end))),
        (ch.ACCELERATION, T[ch.ACCELERATION.type_name](
            header=header(block.t0, "wing"), **common, plunge=a[0], pitch=a[1],
            leading_edge=a[2])),
    ]
    if displacement:
        out.append((ch.DISPLACEMENT, T[ch.DISPLACEMENT.type_name](
            header=header(block.t0, "wing"), **common, plunge=d[0], pitch=d[1],
            leading_edge=d[2], absorber_stroke=d[3])))
    out += [
        (ch.EXCITATION, T[ch.EXCITATION.type_name](
            header=header(block.t0), **common, aileron_force=block.force)),
        (ch.FLIGHT_CONDITION, T[ch.FLIGHT_CONDITION.type_name](
            header=header(block.t0), airspeed=float(block.airspeed[0]),
            air_density=float(block.density[0]))),
    ]
    if state is not None:
        out.append((ch.DAMPER_STATE, T[ch.DAMPER_STATE.type_name](
            header=header(state.time), commanded_damping=float(state.commanded_damping),
            applied_damping=float(state.applied_damping), min_damping=float(state.min_damping),
            max_damping=float(state.max_damping), command_age=float(state.command_age),
            status=int(state.status), source=state.source, mode=int(state.mode),
            switching_rate=float(state.switching_rate))))
    return out


def diagnostics_message(t: float, level: str, text: str, values: dict):
    status = T["diagnostic_msgs/msg/DiagnosticStatus"](
        level=ch.DIAGNOSTIC_LEVELS[level], name=ch.FLIGHT_DIAGNOSTIC_NAME, message=text,
        hardware_id=ch.SIMULATOR_HARDWARE_ID,
        values=[T["diagnostic_msgs/msg/KeyValue"](key=k, value=ch.diagnostic_text(v))
                for k, v in values.items()])
    return T[ch.DIAGNOSTICS.type_name](header=header(t), status=[status])


class ReferenceBag:
    """Write a flight message by message as the recorder node would (see the module doc)."""

    def __init__(self, path, rate: float, *, damper_state: bool = True,
                 displacement: bool = True, library: str = "aero_dva.bag.batch_recorder",
                 **options):
        self.rate, self.displacement = rate, displacement
        self.writer = BagWriter(path, library=library, **options)
        for channel in ch.SIMULATOR_BLOCK + (ch.DIAGNOSTICS,):
            if (channel == ch.DAMPER_STATE and not damper_state) or (
                    channel == ch.DISPLACEMENT and not displacement):
                continue
            self.writer.add_topic(channel.name, channel.type_name, qos_profile_yaml())

    def blocks(self, blocks, states=None) -> None:
        for k, block in enumerate(blocks):
            state = None if states is None else states[k]
            for channel, msg in block_messages(block, state, self.rate, self.displacement):
                data = bytes(STORE.serialize_cdr(msg, channel.type_name))
                self.writer.write(channel.name, data, ns(block.t_end))

    def diagnostics(self, t: float, level: str, text: str, values: dict) -> None:
        msg = diagnostics_message(t, level, text, values)
        self.writer.write(ch.DIAGNOSTICS.name,
                          bytes(STORE.serialize_cdr(msg, ch.DIAGNOSTICS.type_name)), ns(t))

    def close(self):
        return self.writer.close()


def write_batch_bag(path, **options):
    """A flight (test_batch_recording.make_flight) through the BatchRecorder: uncompressed
    chunks of 20 kB unless ``options`` say otherwise."""
    from aero_dva.bag.batch_recorder import BatchRecorder
    from tests.unit.aero_dva.bag.test_batch_recording import RATE, make_flight

    blocks, states = make_flight()
    with BatchRecorder(path, RATE, **{"chunk_size": 20_000, **options}) as recorder:
        recorder.write_blocks(blocks, states)
    return path
