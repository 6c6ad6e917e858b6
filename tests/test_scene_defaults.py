"""What a host gets when it leaves things out, and how duplicate ids are refused (igserver/scene/model.py)."""

from __future__ import annotations

from datetime import datetime, timezone

import pytest
from pydantic import ValidationError

from igserver.scene import Scene


def test_default_time_is_a_fixed_aware_utc_instant():
    """A scene without a time renders the same sky on every run and host: a fixed instant (the June
    solstice 2026 at noon UTC), not the server's clock, and aware UTC like every validated time (it is
    written to the wire with its offset)."""
    first, second = Scene(), Scene.model_validate({})
    assert first.time.utc == second.time.utc == datetime(2026, 6, 21, 12, 0, tzinfo=timezone.utc)
    assert first.time.utc.tzinfo is not None and first.time.utc.utcoffset().total_seconds() == 0
    assert first.model_dump(mode="json")["time"]["utc"] in ("2026-06-21T12:00:00Z", "2026-06-21T12:00:00+00:00")


@pytest.mark.parametrize("section,item", [
    ("effects", {"id": "smoke-1", "type": "smoke"}),
    ("lights", {"id": "smoke-1"}),
    ("entities", {"id": "smoke-1", "model": "crate"}),
])
def test_duplicate_ids_are_refused_naming_the_id(section, item):
    with pytest.raises(ValidationError) as info:
        Scene.model_validate({section: [item, dict(item)]})
    message = str(info.value)
    assert "duplicate" in message and "'smoke-1'" in message, message
