"""How much does the world take in, keep and say, and how often?

The world's bounds in one place: its inbox, the quotas of the ground credentials' commands
and of the queries anyone may ask, the events a flood may not multiply, the suspects it
reports and the rejects it logs."""

from __future__ import annotations

INBOX_CAPACITY = 8192
#: s the world waits after its stop for the last report of every vehicle up (each sends one as
#: it closes, AgentStats.final; they come within milliseconds): one frozen or cut off is not waited
#: for longer. It was a fixed wait of this length, a third of a second of every run's end
FINAL_WAIT_S = 0.3
STOP_GRACE_ALIVE_S = 0.5  # s a stop before the start waits for liveliness tokens already on their way
RADIO_KEEP = 8  # radio geometry samples kept to send a (re)joining vehicle (it needs those in force from its join)
#: the reject reasons of the agents' ω checks that say someone forges a vehicle's ω (docs/metrics.md)
SUSPECT_REASONS = ("future", "conflict", "implausible")
#: ... and those that say someone forges the world's own messages to the vehicles (an open fleet)
SUSPECT_WORLD_REASONS = ("radio_conflict",)
#: ... and those of the agents' watch of the world's liveliness token: a token on a key no process
#: declares (a wildcard, ``alive/**``), a second world token while the world's is up (docs/security.md)
SUSPECT_TOKEN_REASONS = ("token_key", "token_extra")
SUSPECT_EVERY = 5.0  # s: at most one suspect event per (vehicle, reason) in this time
MAX_ODOMETRY_EVENTS = 1000  # a robot's odometry_stale / odometry_back events kept; beyond, counted and dropped
MAX_LOGGED_REJECTS = 200  # (sender, reason) pairs logged; beyond, counted only
MAX_WAITING = 1024  # queries held for a lockstep fault's decision; beyond, answered at once
MAX_QUEUED_QUERIES = 256  # command queries waiting for the main thread; beyond, answered busy at once
#: refused commands go to the event log (published, logged, kept in metrics.json) at most this
#: many at once, then REJECTED_EVENTS_PER_S: a flood of bad commands (each answered, each counted
#: in the rejects) is not amplified into as many events; the next one logged says how many were not
REJECTED_EVENTS_BURST = 20
REJECTED_EVENTS_PER_S = 1.0
#: the same for the changes commands made (gains, link, formation, path): a flood of valid commands
#: is not a flood of events either; each change is still made, answered and listed in world/settings
CHANGE_EVENTS_BURST = 20
CHANGE_EVENTS_PER_S = 1.0
#: commands from the ground credentials (every ground station together: Zenoh does not tell the
#: world which session asked, and they share the credentials), queries and puts alike: at most
#: COMMANDS_PER_S a second on average, COMMANDS_BURST at once; past it, answered at once, rejected
#: "busy: at most ... commands per second" and counted as `rate` (docs/ground_station.md)
COMMANDS_PER_S = 20.0
COMMANDS_BURST = 40
#: queries of the world's status, its settings and every vehicle's last telemetry (world/last/*, the
#: ground station's; not a restarting vehicle's own world/last/<id>): at most QUERIES_PER_S a second
#: on each of the three keys, QUERIES_BURST at once; past it, an error reply that says so, counted as
#: `query_rate` (any member of a fleet may ask them, and Zenoh does not tell the world who asked)
QUERIES_PER_S = 20.0
QUERIES_BURST = 40
#: command queries the main thread answers between two looks at the fleet (grants, recording): a
#: burst of them waits its turn rather than holding the fleet's ticks
ANSWERS_PER_PASS = 16
RATE_REFUSAL = (f"busy: at most {COMMANDS_PER_S:g} commands per second from the ground credentials "
                f"({COMMANDS_BURST} at once; a flood): try again")
