"""What does a cdus plug-in package hold? A path family (:mod:`.gerono`) and a vehicle model
(:mod:`.unicycle`), each one object its entry point names (docs/plugins.md)."""
