"""The protocol's promises layer by layer, without a server or GL (fast: these are the tests the mutation
run uses for igserver/protocol/codec.py, state.py and problems.py).

NaN/Inf are refused at two independent layers, each tested alone here: the codec's tree walk (which
names the path where a NaN was found) and the scene model (``allow_inf_nan=False`` on every section).
Either layer switched off must fail a test; the server tests check the two together.
"""

from __future__ import annotations

import json
import math

import msgpack
import pytest

from igserver.protocol import codec
from igserver.protocol.codec import JSON, MSGPACK, Limits, check_tree, decode, encode, negotiate
from igserver.protocol.problems import ProblemError, json_pointer
from igserver.protocol.state import StateStore, stamp_effect_changes
from igserver.scene import Scene
from igserver.scene.patch import apply_patch, deep_merge, patch_from_assignments, set_path

NON_FINITE = [float("nan"), float("inf"), float("-inf")]


def pack(value) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def raises_kind(kind: str, fn, *args) -> ProblemError:
    with pytest.raises(ProblemError) as info:
        fn(*args)
    assert info.value.kind == kind, (info.value.kind, info.value.detail)
    return info.value


# --------------------------------------------------------------------------- layer 1: the codec walk

@pytest.mark.parametrize("value", NON_FINITE)
def test_codec_alone_rejects_non_finite_with_its_path(value):
    tree = {"camera": {"position": [0.0, value, 1.0]}}
    problem = raises_kind("non_finite", decode, pack(tree), MSGPACK)
    assert problem.errors == [{"pointer": "#/camera/position/1", "detail": "NaN and Infinity are not accepted"}]
    assert problem.status == 422
    # Python's JSON extensions (NaN, Infinity, -Infinity) reach the same walk
    literal = {"nan": "NaN", "inf": "Infinity", "-inf": "-Infinity"}[repr(value)]
    problem = raises_kind("non_finite", decode, b'{"time": {"sim_time": ' + literal.encode() + b"}}", JSON)
    assert problem.errors[0]["pointer"] == "#/time/sim_time"


def test_codec_passes_finite_trees_through_unchanged():
    tree = {"camera": {"position": [0.0, -1e7, 1.5], "pitch": 0.0}, "effects": [{"id": "a"}], "x": None,
            "flag": True, "n": 3, "s": "text"}
    assert decode(pack(tree), MSGPACK) == tree
    assert decode(json.dumps(tree).encode(), JSON) == tree
    # no content type is refused (a write must name JSON or msgpack: docs/operations.md, Security)
    assert raises_kind("unsupported_media_type", decode, json.dumps(tree).encode(), "")
    assert decode(pack(tree), "application/x-msgpack; charset=binary") == tree


def test_codec_limits_each_bound_at_its_edge():
    limits = Limits(max_body_bytes=200, max_depth=3, max_string=5, max_array=4, max_map=3)
    check_tree({"a": {"b": {"c": 1}}}, limits)  # depth 3: allowed
    raises_kind("limits", check_tree, {"a": {"b": {"c": {"d": 1}}}}, limits)
    check_tree({"s": "x" * 5}, limits)
    raises_kind("limits", check_tree, {"s": "x" * 6}, limits)
    check_tree([1, 2, 3, 4], limits)
    raises_kind("limits", check_tree, [1, 2, 3, 4, 5], limits)
    check_tree({"a": 1, "b": 2, "c": 3}, limits)
    raises_kind("limits", check_tree, {"a": 1, "b": 2, "c": 3, "d": 4}, limits)
    raises_kind("limits", decode, b"[" + b"1," * 100 + b"1]", JSON, limits)  # 201 bytes
    raises_kind("limits", decode, pack(["x" * 6]), MSGPACK, limits)  # refused by the msgpack decoder itself
    raises_kind("limits", decode, pack(list(range(5))), MSGPACK, limits)
    problem = raises_kind("validation", check_tree, {"a": [b"bin"]})
    assert [set(e) for e in problem.errors] == [{"pointer", "detail"}]  # the documented shape of errors[]
    assert problem.errors[0]["pointer"] == "#/a/0" and problem.errors[0]["detail"]
    raises_kind("malformed", check_tree, {1: 2})


def test_codec_malformed_and_media_types():
    raises_kind("malformed", decode, b"\xc1", MSGPACK)
    raises_kind("malformed", decode, pack({}) + b"\x00", MSGPACK)
    raises_kind("malformed", decode, msgpack.packb({"a": msgpack.ExtType(1, b"x")}), MSGPACK)
    raises_kind("malformed", decode, b"{", JSON)
    raises_kind("malformed", decode, b"\xff\xfe", JSON)
    raises_kind("unsupported_media_type", decode, b"{}", "text/plain")
    raises_kind("limits", decode, b"[" * 5000 + b"]" * 5000, JSON)


def test_negotiation():
    assert negotiate(None, MSGPACK) == MSGPACK and negotiate(None, JSON) == JSON and negotiate(None, None) == JSON
    assert negotiate("application/json", MSGPACK) == JSON
    assert negotiate("application/vnd.msgpack", JSON) == MSGPACK
    assert negotiate("*/*", MSGPACK) == MSGPACK and negotiate("application/*", JSON) == JSON
    assert negotiate("application/json;q=0.5, application/msgpack", None) == MSGPACK  # q decides
    assert negotiate("application/msgpack;q=0, application/json", MSGPACK) == JSON  # q=0 means never
    assert negotiate("application/json, application/msgpack", None) == JSON  # equal q: the client's order
    assert negotiate("application/msgpack;q=bogus, application/json;q=0.1", None) == JSON
    assert negotiate("image/png", MSGPACK) == MSGPACK  # nothing usable: the request's format
    assert codec.is_msgpack("application/problem+msgpack") and codec.is_json("application/problem+json")
    assert codec.base_media_type(" Application/JSON ; charset=utf-8") == "application/json"


def test_encode_round_trips_and_refuses_non_finite():
    tree = {"a": [1, 2.5, "x"], "b": None}
    assert msgpack.unpackb(encode(tree, MSGPACK), raw=False) == tree
    assert json.loads(encode(tree, JSON)) == tree
    with pytest.raises(ValueError):
        encode({"a": math.nan}, JSON)


def test_json_pointer_escapes():
    assert json_pointer(()) == "#"
    assert json_pointer(("a/b", "c~d", 0)) == "#/a~1b/c~0d/0"


# --------------------------------------------------------------------------- layer 2: the scene model

def _float_leaves(tree, path=()):
    if isinstance(tree, dict):
        for key, value in tree.items():
            yield from _float_leaves(value, path + (key,))
    elif isinstance(tree, list):
        for index, value in enumerate(tree):
            yield from _float_leaves(value, path + (index,))
    elif isinstance(tree, float):
        yield path


def _with(tree, path, value):
    node = tree
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return tree


def _full_scene_tree() -> dict:
    """Every section present, one item in every list, every optional section set."""
    return Scene.model_validate({
        "effects": [{"id": "e"}], "lights": [{"id": "l", "flicker": {"enabled": True}}], "entities": [{"id": "b"}],
        "time": {"sun_override": {"elevation": 10.0, "azimuth": 20.0}},
        "camera": {"frustum": {"left": -10.0, "right": 10.0, "bottom": -5.0, "top": 5.0}},
    }).model_dump(mode="json")


def test_model_alone_rejects_non_finite_in_every_float_field():
    """The model without the codec (the store gets the tree directly): every float field, NaN and +-Inf,
    answers kind ``non_finite`` naming that field, whether or not the field has a range."""
    base = _full_scene_tree()
    paths = list(_float_leaves(base))
    assert len(paths) > 40  # the walk found the model's float fields
    store = StateStore(Scene())
    for path in paths:
        for value in NON_FINITE:
            tree = _with(json.loads(json.dumps(base)), path, value)
            problem = raises_kind("non_finite", store.validate_replace, tree)
            assert json_pointer(path) in [e["pointer"] for e in problem.errors], (path, problem.errors)
    # a patch reaches the same layer, and the message prefix is kept in the pointer
    problem = raises_kind("non_finite", store.validate_patch, {"camera": {"pitch": math.nan}}, ("state",))
    assert problem.errors[0]["pointer"] == "#/state/camera/pitch"


# --------------------------------------------------------------------------- the state store

def frozen_store(**kwargs) -> StateStore:
    """A store whose IG clock is paused: ``store.scene`` is then the accepted object itself (a running clock
    hands out copies at the current sim_time)."""
    store = StateStore(Scene(), **kwargs)
    store.clock.paused = True
    return store


def test_store_rejected_patch_or_replace_changes_nothing():
    store = frozen_store()
    scene, revision = store.scene, store.revision
    mixed = {"camera": {"pitch": 10.0}, "weather": {"wind_speed": -5.0}, "host_frame": 9}
    for call in (store.patch, store.validate_patch):
        problem = raises_kind("validation", call, mixed)
        assert problem.errors == [{"pointer": "#/weather/wind_speed", "detail": problem.errors[0]["detail"]}]
        assert store.scene is scene and store.revision == revision
    for call in (store.replace, store.validate_replace):
        raises_kind("validation", call, {**scene.model_dump(mode="json"), **mixed})
        raises_kind("validation", call, [1, 2])
        assert store.scene is scene and store.revision == revision
    raises_kind("validation", store.patch, "not a map")
    assert store.scene is scene and store.revision == revision


def test_store_accepts_whole_messages_and_counts_revisions():
    seen = []
    store = frozen_store(on_accept=seen.append)
    t0 = store.accepted_at
    new = store.patch({"camera": {"pitch": 10.0}, "host_frame": 3})
    assert store.revision == 1 and store.scene is new and seen == [new] and store.accepted_at >= t0
    assert new.camera.pitch == 10.0 and new.host_frame == 3 and new.camera.heading == Scene().camera.heading
    replaced = store.replace({"host_frame": 4})
    assert store.revision == 2 and replaced.camera.pitch == 0.0 and seen[-1] is replaced
    validated = store.validate_patch({"host_frame": 5})
    assert store.revision == 2 and store.scene is replaced  # validating alone accepts nothing
    assert store.set_validated(validated) is store.scene and store.revision == 3


def test_store_wait_for_change():
    import asyncio

    async def scenario():
        store = StateStore(Scene())
        assert await store.wait_for_change(store.revision + 1, timeout=0.01) is True  # already past
        assert await store.wait_for_change(store.revision, timeout=0.01) is False  # nothing happened
        waiter = asyncio.create_task(store.wait_for_change(store.revision, timeout=5.0))
        await asyncio.sleep(0)
        store.patch({"host_frame": 1})
        assert await waiter is True

    asyncio.run(scenario())


def test_effect_changes_are_stamped_by_the_ig():
    old = Scene.model_validate({"time": {"sim_time": 5.0}, "effects": [{"id": "a", "changed_at": 1.0},
                                                                       {"id": "b", "changed_at": 2.0}]})
    # b switches off, c appears, a is echoed with a client's changed_at: only switches are stamped
    new = apply_patch(old, {"time": {"sim_time": 9.0}, "effects": [
        {"id": "a", "changed_at": 7.0}, {"id": "b", "active": False, "changed_at": 2.0}, {"id": "c"}]})
    stamped = {e.id: e.changed_at for e in stamp_effect_changes(old, new).effects}
    assert stamped == {"a": 1.0, "b": 9.0, "c": 9.0}
    unchanged = apply_patch(old, {"host_frame": 2})
    assert stamp_effect_changes(old, unchanged) is unchanged  # nothing to stamp: the same object


# --------------------------------------------------------------------------- patches

def test_patch_merges_maps_and_replaces_lists():
    assert deep_merge({"a": {"x": 1, "y": 2}, "l": [1, 2]}, {"a": {"y": 3}, "l": [9]}) == {"a": {"x": 1, "y": 3}, "l": [9]}
    assert deep_merge({"a": 1}, {"a": {"b": 2}}) == {"a": {"b": 2}}
    base = Scene.model_validate({"lights": [{"id": "l1"}, {"id": "l2"}]})
    assert [l.id for l in apply_patch(base, {"lights": [{"id": "l3"}]}).lights] == ["l3"]
    with pytest.raises(TypeError):
        apply_patch(base, [1])


def test_assignments_become_a_patch():
    assert set_path("camera.pitch", 10) == {"camera": {"pitch": 10}}
    assert patch_from_assignments(["camera.pitch=10", "camera.heading=5.5", "time.utc=2027-01-01T00:00:00Z",
                                   "effects=[]"]) == {
        "camera": {"pitch": 10, "heading": 5.5}, "time": {"utc": "2027-01-01T00:00:00Z"}, "effects": []}
    with pytest.raises(ValueError):
        patch_from_assignments(["camera.pitch"])
    with pytest.raises(ValueError):
        set_path("..", 1)


# --------------------------------------------------------------------------- found by mutation testing
# Each test below kills mutants that survived the suite (scripts/mutation.sh); the comment says which
# behaviour the mutant broke.

def test_negotiation_edges():
    # an empty range is skipped, not the end of the list
    assert negotiate(" , application/msgpack", JSON) == MSGPACK
    # a range without q counts as q=1, equal to an explicit q=1: the client's order decides
    assert negotiate("application/json;q=1, application/msgpack", None) == JSON
    assert negotiate("application/msgpack, application/json", None) == MSGPACK  # order, not name
    # q is the number after "q=" (q=0.5 is not 5)
    assert negotiate("application/json;q=0.5, application/msgpack;q=0.25", None) == JSON
    # parameters are split at ";" (not whitespace)
    assert negotiate("application/msgpack;q=0.1, application/json;q=0.9", MSGPACK) == JSON
    # q=0 alone means "never": the request's format
    assert negotiate("application/msgpack;q=0", JSON) == JSON
    # a wildcard before a specific type answers in the request's format
    assert negotiate("*/*, application/json", MSGPACK) == MSGPACK
    assert negotiate("application/*, application/json", MSGPACK) == MSGPACK
    # only the first parameter boundary matters for the media type
    assert codec.base_media_type("application/json; a=1; b=2") == "application/json"


def test_msgpack_decoder_itself_bounds_what_it_builds():
    """The msgpack decoder refuses over-long strings, arrays, maps and binaries while decoding, before any
    tree exists (the tree walk would only see them after the memory was spent)."""
    limits = Limits(max_body_bytes=10_000, max_depth=16, max_string=5, max_array=4, max_map=3)
    for value in (["x" * 6], list(range(5)), {str(i): i for i in range(4)}):
        raises_kind("limits", codec._loads_msgpack, pack(value), limits)
    assert codec._loads_msgpack(pack({"a": [1, 2, 3, 4]}), limits) == {"a": [1, 2, 3, 4]}
    # keys must be strings already in the decoder; extension types (timestamps too) are refused
    raises_kind("malformed", codec._loads_msgpack, msgpack.packb({1: 2}), limits)
    raises_kind("malformed", codec._loads_msgpack, msgpack.packb(msgpack.Timestamp(1, 0)), limits)
    assert codec._loads_msgpack(pack({"s": "text"}), limits) == {"s": "text"}  # str, not bytes


def test_msgpack_nesting_beyond_the_decoder_stack_is_a_limit():
    deep = b"\x91" * 5000 + b"\xc0"  # 5000 nested one-element arrays
    problem = raises_kind("limits", decode, deep, MSGPACK)
    assert "deep" in problem.detail


def test_depth_of_arrays_and_the_body_size_edge():
    limits = Limits(max_body_bytes=32, max_depth=3, max_string=5, max_array=4, max_map=3)
    check_tree([[[1]]], limits)
    raises_kind("limits", check_tree, [[[[1]]]], limits)
    raises_kind("limits", check_tree, [{"a": [[1]]}], limits)
    body = b"[" + b"1," * 14 + b"1] "  # exactly max_body_bytes: accepted
    assert len(body) == 32 and decode(body, JSON, limits.__class__(max_body_bytes=32, max_array=16)) == [1] * 15
    raises_kind("limits", decode, body + b" ", JSON, limits)
    # the caller's limits reach the tree walk (a JSON string is only checked there)
    raises_kind("limits", decode, b'["' + b"x" * 6 + b'"]', JSON, limits)


def test_encode_exact_bytes():
    assert encode({"a": [1, 2]}, JSON) == b'{"a":[1,2]}'
    packed = encode({"b": b"\x00\x01", "s": "x"}, MSGPACK)
    assert msgpack.unpackb(packed, raw=False) == {"b": b"\x00\x01", "s": "x"}  # bin stays bin


def test_non_map_messages_name_the_root():
    store = StateStore(Scene())
    for call in (store.validate_patch, store.validate_replace):
        problem = raises_kind("validation", call, [1])
        assert problem.errors == [{"pointer": "#", "detail": "expected a map"}] and problem.detail
    problem = raises_kind("validation", store.validate_replace, {"camera": {"pitch": 95.0}}, ("state",))
    assert problem.errors[0]["pointer"] == "#/state/camera/pitch"


def test_echoed_changed_at_alone_is_restored():
    old = Scene.model_validate({"effects": [{"id": "a", "changed_at": 1.0}]})
    echoed = apply_patch(old, {"effects": [{"id": "a", "changed_at": 7.0}]})
    assert [e.changed_at for e in stamp_effect_changes(old, echoed).effects] == [1.0]


def test_assignment_values_may_contain_equals_signs():
    assert patch_from_assignments(["weather.note=a=b=c"]) == {"weather": {"note": "a=b=c"}}


def test_problem_from_validation_error_lists_every_field():
    store = StateStore(Scene())
    problem = raises_kind("validation", store.validate_patch,
                          {"camera": {"pitch": 95.0, "heading": 999.0}, "weather": {"wind_speed": -1.0}})
    pointers = [e["pointer"] for e in problem.errors]
    assert sorted(pointers) == ["#/camera/heading", "#/camera/pitch", "#/weather/wind_speed"]
    assert all(e["detail"] and "http" not in e["detail"] for e in problem.errors)  # pydantic's words, no URL
    # the summary names the first field and counts the others
    assert problem.detail.startswith(pointers[0] + ": ") and problem.detail.endswith(" (and 2 more)")
    single = raises_kind("validation", store.validate_patch, {"camera": {"pitch": 95.0}})
    assert single.detail.startswith("#/camera/pitch: ") and "more" not in single.detail
    assert str(single) == single.detail  # the exception's message is the detail


def test_problem_document_members():
    problem = ProblemError("render_unavailable", "down", headers={"Retry-After": "1"})
    assert problem.headers == {"Retry-After": "1"} and problem.status == 503
    doc = problem.document("/v1/frame")
    assert doc["detail"] == "down" and doc["instance"] == "/v1/frame" and doc["kind"] == "render_unavailable"
    assert doc["type"].endswith("/render_unavailable") and "errors" not in doc
    bare = ProblemError("not_found")
    assert str(bare) == bare.title and "detail" not in bare.document() and "instance" not in bare.document()
