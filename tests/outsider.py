"""An outsider's Zenoh client, for the access-control tests (unit and end to end)."""

from __future__ import annotations

import json

import zenoh


def raw_client(endpoint: str) -> zenoh.Config:
    """A plain Zenoh client: no credentials, no retries, multicast scouting off."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return conf
