"""Mitsuba 3's ``shapegroup`` and ``instance`` shapes (src/shapes/shapegroup.cpp, instance.cpp),
through the builder's shape groups (loaders/instancing.py).

A ``shapegroup`` holds shapes, each with its BSDF, media and own ``to_world``; it draws nothing by
itself.  An ``instance`` names one shapegroup (a ``<ref>``, or the group written inside it) and
draws its shapes moved by its ``to_world``: a shape lands at instance.to_world @ shape.to_world.
As in Mitsuba, a shapegroup inside a shapegroup and an instance inside a shapegroup are errors, and
an instance takes exactly one shapegroup and nothing else.  Mitsuba refuses emitters in a
shapegroup ("Instancing of emitters is not supported"); we render them, with a warning.
"""
from __future__ import annotations

from .builder import error_at
from .instancing import ShapeGroup, add_instance
from .mitsuba_plugins import SURFACE_EMITTERS
from .mitsuba_xml import MiObject


def shapegroup(imp, obj: MiObject) -> ShapeGroup:
    """The group of a ``<shape type="shapegroup">``, its shapes recorded on first use."""
    groups = imp.__dict__.setdefault("_shapegroups", {})
    if id(obj) in groups:
        return groups[id(obj)][1]
    b = imp.b
    if b.recording is not None:
        raise error_at(obj.node.pos, f"{obj.label()} inside a shapegroup: nested shapegroups are not permitted")
    group = b.begin_group(obj.id or f"shapegroup at {obj.node.pos}")
    try:
        for child in obj.children:
            if child.tag != "shape":
                imp.warn(child.node.pos, f"{child.label()} in {obj.label()}: a shapegroup holds only shapes; ignored")
            elif child.type == "shapegroup":
                raise error_at(child.node.pos, f"{child.label()} in {obj.label()}: nested shapegroups are "
                                               "not permitted")
            elif child.type == "instance":
                raise error_at(child.node.pos, f"{child.label()} in {obj.label()}: nested instancing is not "
                                               "permitted")
            else:
                if any(em.type in SURFACE_EMITTERS for em in child.children_of("emitter")):
                    imp.warn(child.node.pos, f"{child.label()} in {obj.label()}: an emitter in a shapegroup "
                                             "(Mitsuba refuses it: instancing of emitters is not supported); "
                                             "each instance emits")
                imp.shape(child)
    finally:
        b.end_group()
    groups[id(obj)] = (obj, group)  # keeps obj alive: the key is its id
    if group.empty:
        imp.warn(obj.node.pos, f"{obj.label()}: no shape that we can render; its instances draw nothing")
    imp.unused(obj)
    return group


def instance(imp, obj: MiObject) -> None:
    """An ``<shape type="instance">``: its shapegroup's shapes moved by its to_world."""
    if imp.b.recording is not None:
        raise error_at(obj.node.pos, f"{obj.label()} inside a shapegroup: nested instancing is not permitted")
    groups = [c for c in obj.children if c.tag == "shape" and c.type == "shapegroup"]
    for other in obj.children:
        if not (other.tag == "shape" and other.type == "shapegroup"):
            raise error_at(other.node.pos, f"{other.label()} in {obj.label()}: only a shapegroup can be "
                                           "specified in an instance")
    if len(groups) != 1:
        raise error_at(obj.node.pos, f"{obj.label()}: " + ("needs a reference to a shapegroup (<ref id=...>)"
                                                          if not groups else "only one shapegroup per instance"))
    group = shapegroup(imp, groups[0])
    add_instance(imp.b, group, obj.transform("to_world"), f"{obj.node.pos}: {obj.label()}")
    imp.unused(obj)
