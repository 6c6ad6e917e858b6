"""Component Control -> effects and lights on entities (the scheme is docs/cigi.md's table).

Class 0 (entity), instance id = the CIGI entity number the item sits on (it follows the entity):
component ids 1-63 are volumetric effects ``cigi.N.fxC``, 64-127 point lights ``cigi.N.lightC``.
The data words are raw 32-bit words; those that carry a float are read as float32 here.
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING

from .codec import Malformed
from .packets_host import ComponentControl, ShortComponentControl
from .session import entity_id

if TYPE_CHECKING:
    from .mapping import Work

EFFECT_COMPONENTS = range(1, 64)  # Component Control (class 0 = entity) ids of volumetric effects
LIGHT_COMPONENTS = range(64, 128)  # ... and of point lights
EFFECT_TYPES = ("fire", "smoke", "gas_burner")  # data1 of an effect component
ENTITY_CLASS = 0


def word_float(word: int) -> float:
    """A Component Control data word read as the float32 it carries; non-finite makes the message malformed."""
    value = struct.unpack("<f", struct.pack("<I", word))[0]
    if value != value or value in (float("inf"), float("-inf")):
        raise Malformed("non_finite", f"component data word 0x{word:08x} is not a finite float")
    return value


def component(work: "Work", p: ComponentControl | ShortComponentControl) -> None:
    if p.component_class != ENTITY_CLASS or (p.component_id not in EFFECT_COMPONENTS
                                             and p.component_id not in LIGHT_COMPONENTS):
        work.plan.skipped[f"component_class_{p.component_class}"] += 1
        return
    work.entity(p.instance_id, "Component Control")
    words = [p.data1, p.data2, getattr(p, "data3", 0), getattr(p, "data4", 0), getattr(p, "data5", 0)]
    if p.component_id in EFFECT_COMPONENTS:
        _effect(work, p, words)
    else:
        _light(work, p, words)
    work.moved = True  # place it at its entity


def _effect(work: "Work", p, words: list[int]) -> None:
    key = f"{entity_id(p.instance_id)}.fx{p.component_id}"
    if p.component_state == 2:
        work.drop("effects", lambda i: i != key)
        return
    if p.component_state not in (0, 1):
        raise Malformed("out_of_range", f"effect component state {p.component_state} (0 stop, 1 start, 2 remove)")
    if words[0] >= len(EFFECT_TYPES):
        raise Malformed("out_of_range", f"effect type {words[0]} (0 fire, 1 smoke, 2 gas burner)")
    diameter, intensity, fade = (word_float(w) for w in words[1:4])
    item = dict(work.item("effects", key) or {"id": key, "seed": p.instance_id * 64 + p.component_id})
    item.update(type=EFFECT_TYPES[words[0]], active=p.component_state == 1, emits_smoke=bool(words[4] & 1))
    # a zero word keeps the model's default (a Short Component Control carries data 1-2 only)
    for name, value in (("diameter", diameter), ("intensity", intensity), ("fade", fade)):
        if value:
            item[name] = value
    work.put("effects", item)


def _light(work: "Work", p, words: list[int]) -> None:
    key = f"{entity_id(p.instance_id)}.light{p.component_id}"
    lights = work.session.lights
    if p.component_state == 2:
        work.drop("lights", lambda i: i != key)
        lights.pop(key, None)
        return
    if p.component_state not in (0, 1):
        raise Malformed("out_of_range", f"light component state {p.component_state} (0 off, 1 on, 2 remove)")
    intensity, range_m, height = word_float(words[0]), word_float(words[2]), word_float(words[3])
    # the intensity while on is remembered: "off" is intensity 0, "on" again restores it
    memory = dict(lights.get(key) or {"intensity": 1000.0, "height": 0.0})
    lights[key] = memory
    if intensity:
        memory["intensity"] = intensity
    memory["height"] = height  # m above the entity's origin
    item = dict(work.item("lights", key) or {"id": key})
    item["intensity"] = memory["intensity"] if p.component_state == 1 else 0.0
    if words[1]:
        rgb = words[1] & 0xFFFFFF
        item["color"] = [(rgb >> 16) / 255.0, (rgb >> 8 & 0xFF) / 255.0, (rgb & 0xFF) / 255.0]
    if range_m:
        item["range"] = range_m
    work.put("lights", item)
