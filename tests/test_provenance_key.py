"""The run key with the options' dictionary computed once per batch: the same key."""

import dataclasses
import hashlib
import json

from wheelcal import __version__
from wheelcal.batch.provenance import run_key
from wheelcal.session.compute import SessionOptions


def _plain_run_key(sha: str, options: SessionOptions, produces: dict) -> str:
    payload = {
        "input": sha,
        "options": dataclasses.asdict(options),
        "produces": produces,
        "version": __version__,
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()


def test_run_keys_are_the_plain_computation():
    variants = [
        SessionOptions(),
        SessionOptions(radius_m=0.3, rrd=True),
        SessionOptions(defaults=(("radius_m", 0.28),)),
        SessionOptions(defaults=(("sensor_id", ["a", "b"]),)),  # unhashable: computed each time
    ]
    for options in variants:
        for sha in ("0" * 64, "f" * 64):
            for produces in ({"rrd": False}, {"rrd": True}):
                want = _plain_run_key(sha, options, produces)
                assert run_key(sha, options, produces) == want
                assert run_key(sha, options, produces) == want  # and again, from the cache
    assert len({run_key("0" * 64, o, {"rrd": False}) for o in variants}) == len(variants)
