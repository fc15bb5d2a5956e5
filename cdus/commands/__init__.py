"""What may an operator, a scenario or the wire ask a running fleet? The run-time commands, one typed room.

Each command (stop, pause, resume, gains, link, formation, path, radio; kill, pause, resume and
restart of one vehicle) is one frozen type that holds, in one place:

- its names (:mod:`cdus.commands.base`, ``NAMES``): the ground station's CLI word, the wire op
  (and the older spelling still decoded), the scenario ``[[event]]``'s action;
- its parse from raw fields, ``parse(fields) -> Command | Rejected`` (cdus.wire.rejected): the
  same for a ground station's arguments, a wire message and a scenario event
  (:mod:`cdus.commands.parse` turns each into the same fields);
- the first tick it applies from (:mod:`cdus.commands.effect`, one rule for both clocks);
- how it applies to a :class:`cdus.core.node.VehicleNode`: ``apply(node, tick, ...) ->
  Applied | Rejected``, the outcome as a value.

The modules: ``base`` (names, outcome), ``effect`` (the effect tick), ``gains`` (the gains rule),
``fleet`` (stop, pause, resume), ``vehicle`` (a vehicle's kill, pause, resume, restart),
``changes`` (link, formation, path, radio) and ``parse`` (the three entries and the registry).
This package imports nothing itself: :mod:`cdus.scenario` imports ``gains`` and ``vehicle`` while
``changes`` imports the scenario's path and phase checks, and an eager import here would close
that loop. Pure: no Zenoh, no clock, no threads.
"""
