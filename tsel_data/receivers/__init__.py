"""Receivers: every microphone array, ambisonic microphone, stereo pair or pair of ears a
scene can be heard by, each declared once as a :class:`ReceiverSpec`.

    spec = receiver("tetra")            # by name or alias ("mic")
    pose = ArrayPose("mic4", centre=(4.0, 3.0, 1.2), yaw=30.0, side=0.11)
    pose.mics(), pose.channel_names(), pose.spec.model

Import order inside the package (each module imports only those above it)::

    spec        ReceiverSpec, Capsules, first-order patterns
    builtin     the built-in receivers, one entry each
    registry    lookup by name or alias
    pose        ArrayPose: a receiver in a room
    doc         the receivers table of docs/format.md
    stereo      the headphone decode of every receiver (``tsel inspect --wav``)

Arrays from the config (capsule tables checked and resolved) are ``config/receiver.py``.
"""
from .builtin import TETRA_ANGLES, TETRA_RADIUS, mic4_positions, tetra_positions
from .pose import ArrayPose, array_radius, mic_positions
from .registry import ALIASES, NAMES, RECEIVERS, canonical, receiver
from .spec import MAX_CHANNELS, PATTERN_ALPHA, Capsules, ReceiverSpec

__all__ = ["ALIASES", "ArrayPose", "Capsules", "MAX_CHANNELS", "NAMES", "PATTERN_ALPHA", "RECEIVERS",
           "ReceiverSpec", "TETRA_ANGLES", "TETRA_RADIUS", "array_radius", "canonical", "mic4_positions",
           "mic_positions", "receiver", "tetra_positions"]
