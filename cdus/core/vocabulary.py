"""What is each thing called? The fleet's vocabularies, each defined once.

The core decides with these words, the wire checks what arrives against them, the records
and the docs use them. This module imports nothing, so the wire (below the core) may import
it: tests/test_layers.py ranks it with the wire. Add a word here and every user of the
vocabulary (the emulator, the decoders, the metrics) takes it.
"""

from __future__ import annotations

#: who drives time in a fleet of processes (docs/architecture.md); not how a run is run
#: (cdus.api.RUNNERS: in this process or as a launched fleet)
CLOCKS = ("lockstep", "realtime")

#: a vehicle's kind -> the dimension it moves in (a boat on the water, a drone in the air)
DIMENSIONS: dict[str, int] = {"usv": 2, "uav": 3}
KINDS = tuple(DIMENSIONS)

#: why the link emulator (cdus.core.link) dropped a message
DROP_CAUSES = ("loss", "burst", "down", "partition")
#: a directed link's state as the emulator sees it
LINK_STATES = ("up", "lossy", "down")
#: the link emulator's counts besides its drops by cause (LinkFaultCounters.as_dict)
FAULT_COUNTERS = ("sent", "dropped", "duplicated", "delayed")

#: why the radio channel (cdus.core.radio) dropped a message
CHANNEL_CAUSES = ("range", "fading", "collision", "queue")
#: why the radio path (cdus.core.radiolink) dropped one: the hand-set [link] fault, then the channel's
RADIO_CAUSES = ("fault", *CHANNEL_CAUSES)

#: a vehicle's state in a fleet's roster (cdus.core.events): stepping, paused (by a fault or a
#: ground station), gone (killed, lost)
ROSTER_STATES = ("live", "paused", "gone")

#: what a scenario ``[[event]]`` does to one vehicle's process (cdus.core.events plans the roster
#: from them; they are the event names of cdus.commands.vehicle's Kill, PauseVehicle,
#: ResumeVehicle and Restart, whose CLI words and wire ops differ: ``pause-vehicle``, ``pause_vehicle``)
FAULT_ACTIONS = ("kill", "pause", "resume", "restart")
KILL, PAUSE, RESUME, RESTART = FAULT_ACTIONS
#: what a scenario ``[[event]]`` changes besides a vehicle's process: the formation, one vehicle's
#: path (the event names of cdus.commands.changes' Formation and Path)
CHANGE_ACTIONS = ("formation", "path")
FORMATION, PATH = CHANGE_ACTIONS
