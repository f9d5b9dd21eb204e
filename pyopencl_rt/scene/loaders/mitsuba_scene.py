"""Mitsuba 3 XML scene files (``.xml``): the plugin objects of :mod:`.mitsuba_xml` mapped onto our
scene; docs/SCENE_FORMAT.md ("Mitsuba 3 XML") lists each plugin and parameter and what it becomes.

The plugins and parameters we take are those of :mod:`.mitsuba_plugins`; any other plugin type
or parameter is refused with one line naming it (Mitsuba refuses a parameter its plugin does not
read, too).  A parameter we take but that this mapping does not read in its context is one
warning naming the element and its file position.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..lights import MITSUBA_TYPES as MITSUBA_LIGHTS
from ..model import Environment, RenderSettings
from ..pixel_filter import PixelFilter
from ..shapes import MITSUBA_TYPES as MITSUBA_SHAPES
from ..shapes.frames import ShapeMitsubaReading, coordinate_system
from .builder import EnvMap, SceneBuilder, camera_from_matrix, cylinder_mesh, error_at, rectangle_mesh
from .mitsuba_meshes import CURVED_SEGMENTS, flat, mitsuba_cube_mesh, mitsuba_disk_mesh, mitsuba_sphere_mesh
from ..media import MediumInterface
from .mitsuba_bsdf import BsdfMapper, color_value
from .mitsuba_instances import instance, shapegroup
from .mitsuba_media import MediaMapper
from .mitsuba_plugins import ANY_TEXTURE_NAME, HONOURED, SURFACE_EMITTERS, accepted, refusal
from .mitsuba_xml import Document, MiObject


# hdrfilm's filter when it names none (and the film's when there is no film)
MITSUBA_DEFAULT_FILTER = PixelFilter("gaussian", (2.0, 2.0), sigma=0.5)


def reads_uv(material) -> bool:
    """Whether shading ``material`` reads the surface's uv or dp/du: a texture (reflectance,
    roughness, emission, a normal or bump map) or an anisotropic frame, its own or a blended one's."""
    return bool(material.textures()) or material.is_anisotropic or any(reads_uv(m) for m in material.blend)


def load_mitsuba_xml(path, name: str | None = None, defines: dict | None = None):
    """The Scene of a Mitsuba 3 XML file; ``defines`` are ``$name`` values that take precedence
    over the file's ``<default>``s (the CLI's ``--define name=value``)."""
    path = Path(path)
    name = name or str(path)
    builder = SceneBuilder(name, "mitsuba-xml")
    doc = Document(path, name, defines, builder.warn)
    _Importer(doc, builder, path).run()
    return builder.build()


class _Importer:
    def __init__(self, doc: Document, builder: SceneBuilder, path: Path):
        self.doc, self.b, self.path = doc, builder, path
        self.bsdfs = BsdfMapper(self)
        self.media = MediaMapper(self)
        self._null_material = None

    def warn(self, position, what):
        self.b.warn(position, what)

    def unused(self, obj: MiObject) -> None:
        """Refuses a parameter of ``obj`` that mitsuba_plugins does not list for its plugin; one
        warning per listed parameter the mapping did not read (its neutral ones aside)."""
        known = accepted(obj.tag, obj.type)
        if known is None:
            raise error_at(obj.node.pos, refusal(obj))
        honoured = HONOURED[obj.tag][obj.type]
        any_texture = (obj.tag, obj.type) in ANY_TEXTURE_NAME
        for pname, p in obj.props.items():
            if any_texture and p.kind == "object" and p.value.tag == "texture":
                continue
            if pname not in known:
                raise error_at(p.node.pos, f'<{p.kind} name="{pname}"> of {obj.label()}: parameter not supported')
            if pname in honoured and pname not in obj.used:
                self.warn(p.node.pos, f'<{p.kind} name="{pname}"> of {obj.label()}: not read here; ignored')

    def refuse_type(self, obj: MiObject) -> None:
        """One error line for a plugin type we do not render (never replaced by another)."""
        if obj.type not in HONOURED.get(obj.tag, {}):
            raise error_at(obj.node.pos, refusal(obj))

    def resolve(self, fname, obj: MiObject) -> Path:
        return self.doc.resolve(fname, obj.node)

    # -- the scene -------------------------------------------------------------------------------

    def run(self) -> None:
        sensors = [o for o in self.doc.objects if o.tag == "sensor"]
        integrators = [o for o in self.doc.objects if o.tag == "integrator"]
        settings = RenderSettings(width=768, height=576, spp=4, max_depth=-1, rr_depth=5,
                                  filter=MITSUBA_DEFAULT_FILTER, light_sampler="uniform")
        # light_sampler: Mitsuba picks an emitter by its sampling_weight (scene.cpp), then a point on
        # its shape uniformly by area (an area emitter on a mesh: Mesh::sample_position)
        self.b.settings = settings
        for extra in sensors[1:] + integrators[1:]:
            self.warn(extra.node.pos, f"{extra.label()}: only the first {extra.tag} is used; ignored")
        if integrators:
            self.integrator(integrators[0], settings)
        if sensors:
            self.sensor(sensors[0], settings)
        for obj in self.doc.objects:
            if obj.tag == "shape" and obj.type in ("shapegroup", "instance"):  # loaders/mitsuba_instances.py
                (shapegroup if obj.type == "shapegroup" else instance)(self, obj)
            elif obj.tag == "shape":
                self.shape(obj)
            elif obj.tag == "emitter" and obj.type in SURFACE_EMITTERS and obj in self.doc.referenced:
                continue  # declared at the top level, used by the shapes that <ref> it
            elif obj.tag == "emitter":
                self.emitter(obj)
            elif obj.tag == "medium":
                self.media.medium(obj)  # made (and checked) as Mitsuba makes it; in the scene where used
            elif obj.tag in ("bsdf", "texture", "phase", "volume"):
                continue  # used through references
            elif obj.tag not in ("sensor", "integrator"):
                raise error_at(obj.node.pos, f"{obj.label()}: not supported at the top level of a scene")

    def integrator(self, obj: MiObject, settings: RenderSettings) -> None:
        self.refuse_type(obj)
        nested = obj.children_of("integrator")
        if obj.type in ("aov", "moment") and nested:
            # a wrapper that adds variance or AOV images beside its nested integrator's image:
            # we render the nested integrator's image, without a word (its own parameters, the
            # aovs list, describe only the extra images)
            for extra in nested[1:]:
                self.warn(extra.node.pos, f"{extra.label()} in {obj.label()}: only the first nested "
                                          "integrator is rendered; ignored")
            return self.integrator(nested[0], settings)
        if obj.type == "direct":
            settings.max_depth = 2
        else:
            if obj.type in ("volpath", "volpathmis"):  # the weights of chromatic media (scene/media.py)
                settings.spectral_mis = obj.type == "volpathmis" and bool(obj.boolean("use_spectral_mis", True))
            depth = obj.integer("max_depth", -1, minimum=-1)
            if depth == 0:
                raise error_at(obj.props["max_depth"].node.pos, f"{obj.label()}: max_depth 0 renders nothing")
            settings.max_depth = depth
            settings.rr_depth = obj.integer("rr_depth", 5, minimum=0)
        if obj.boolean("hide_emitters", False):
            raise error_at(obj.props["hide_emitters"].node.pos, f"{obj.label()}: hide_emitters true is not "
                                                                "supported (emitters are always visible)")
        self.unused(obj)

    def sensor(self, obj: MiObject, settings: RenderSettings) -> None:
        films = obj.children_of("film")
        film = films[0] if films else None
        if film is not None:
            self.refuse_type(film)
            settings.width = film.integer("width", 768, minimum=1)
            settings.height = film.integer("height", 576, minimum=1)
            settings.filter = self.rfilter(film)
            for extra in film.children:
                if extra.tag != "rfilter":
                    raise error_at(extra.node.pos, f"{extra.label()} in {film.label()}: not supported")
            self.unused(film)
        for sampler in obj.children_of("sampler"):
            self.refuse_type(sampler)
            settings.spp = sampler.integer("sample_count", 4, minimum=1)
            seed = sampler.integer("seed", None)
            if seed is not None:
                settings.seed = seed & 0xFFFFFFFF
            self.unused(sampler)
        media = obj.children_of("medium") + [p.value for p in obj.props.values()
                                             if p.kind == "object" and p.value.tag == "medium"]
        obj.used.update(n for n, p in obj.props.items() if p.kind == "object" and p.value.tag == "medium")
        if media:  # Mitsuba's sensor takes its one medium whatever its name
            self.b.camera_medium = self.b.medium_index(self.media.medium(media[0]))
        for extra in obj.children:
            if extra.tag not in ("film", "sampler", "medium"):
                raise error_at(extra.node.pos, f"{extra.label()} in {obj.label()}: not supported")
        if obj.type == "orthographic":
            return self.orthographic(obj, settings)
        self.refuse_type(obj)
        fov, axis = _mitsuba_fov(obj)
        aperture, focus = 0.0, None
        if obj.type == "thinlens":
            if not obj.has("aperture_radius"):
                raise error_at(obj.node.pos, f'{obj.label()} needs <float name="aperture_radius">')
            aperture = obj.float("aperture_radius", minimum=0.0)
            far = obj.props["far_clip"].value if obj.has("far_clip") else 1e4  # Mitsuba's default focus
            focus = obj.float("focus_distance", far, positive=True)
        m = obj.transform("to_world")
        m = np.eye(4) if m is None else m
        if abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise error_at(obj.props["to_world"].node.pos, f"{obj.label()}: to_world is singular")
        self.b.camera, self.b.mirror = camera_from_matrix(m, fov, -1.0, aperture=aperture,
                                                          focus=focus if aperture > 0 else None, fov_axis=axis)
        self.unused(obj)

    def orthographic(self, obj: MiObject, settings: RenderSettings) -> None:
        """Mitsuba's film spans local x in [-1, 1] and y in [-1, 1] / aspect (aspect = width /
        height), at local z = near_clip, seen along local +z, with image right on local -x; to_world
        scales it (a <scale x="s" y="s"/> before the lookat: a film 2 s wide)."""
        m = obj.transform("to_world")
        m = np.eye(4) if m is None else m
        if abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise error_at(obj.props["to_world"].node.pos, f"{obj.label()}: to_world is singular")
        near = obj.float("near_clip", 1e-2, minimum=0.0)
        half_width = float(np.linalg.norm(m[:3, 0]))
        half_height = float(np.linalg.norm(m[:3, 1])) * settings.height / settings.width
        frame = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
        if not np.isclose(half_width / settings.width, half_height / settings.height, rtol=1e-5) or \
                not np.allclose(frame.T @ frame, np.eye(3), atol=1e-6):
            self.warn(obj.node.pos, f"{obj.label()}: to_world scales x and y unevenly or shears: our pixels are "
                                    "square, the film's height is kept")
        at_near = m.copy()
        at_near[:3, 3] = m[:3, 3] + near * m[:3, 2]  # the rays start on the near plane
        self.b.camera, self.b.mirror = camera_from_matrix(at_near, 40.0, -1.0, projection="orthographic",
                                                          extent=2.0 * half_height)
        self.unused(obj)

    def rfilter(self, film: MiObject) -> PixelFilter:
        """The film's <rfilter> (Mitsuba's default when it has none: gaussian, stddev 0.5)."""
        filters = film.children_of("rfilter")
        for extra in filters[1:]:
            self.warn(extra.node.pos, f"{extra.label()} in {film.label()}: only the first rfilter is used; ignored")
        if not filters:
            return MITSUBA_DEFAULT_FILTER
        rf, t = filters[0], filters[0].type
        if t == "box":
            flt = PixelFilter("box", (0.5, 0.5))
        elif t == "tent":
            r = rf.float("radius", 1.0, positive=True)
            flt = PixelFilter("tent", (r, r))
        elif t == "gaussian":
            sigma = rf.float("stddev", 0.5, positive=True)
            flt = PixelFilter("gaussian", (4 * sigma, 4 * sigma), sigma=sigma)
        elif t in ("mitchell", "catmullrom"):
            b, c = (rf.float("B", 1 / 3), rf.float("C", 1 / 3)) if t == "mitchell" else (0.0, 0.5)
            flt = PixelFilter("mitchell", (2.0, 2.0), b=b, c=c)
        elif t == "lanczos":
            lobes = rf.integer("lobes", 3, minimum=1)
            flt = PixelFilter("lanczos", (float(lobes), float(lobes)), tau=float(lobes))
        else:
            raise error_at(rf.node.pos, refusal(rf))
        self.unused(rf)
        try:
            return flt.checked()
        except ValueError as exc:
            raise error_at(rf.node.pos, f"{rf.label()}: {exc}") from None

    # -- shapes ----------------------------------------------------------------------------------

    def interface(self, obj: MiObject, bsdfs) -> MediumInterface | None:
        """The shape's medium interface: its interior and exterior media (a transition when either
        is given, as Mitsuba's is_medium_transition), index-matched under a null BSDF."""
        null = bool(bsdfs) and bsdfs[0].type == "null"
        sides = {}
        for side in ("interior", "exterior"):
            p = obj.prop(side) if obj.has(side) else None
            if p is not None:
                if p.kind != "object" or p.value.tag != "medium":
                    raise error_at(p.node.pos, f'{obj.label()}: "{side}" must be a <medium>, got <{p.kind}>')
                sides[side] = self.b.medium_index(self.media.medium(p.value))
        for extra in (p for n, p in obj.props.items() if p.kind == "object" and p.value.tag == "medium"
                      and n not in ("interior", "exterior")):
            raise error_at(extra.node.pos, f'{extra.value.label()} in {obj.label()}: a shape\'s medium is named '
                                           '"interior" or "exterior"')
        for extra in obj.children_of("medium"):
            self.warn(extra.node.pos, f'{extra.label()} in {obj.label()}: a shape\'s medium needs name="interior" or '
                                      'name="exterior"; ignored')
        if not sides and not null:
            return None
        return MediumInterface(sides.get("interior", -1), sides.get("exterior", -1), transition=bool(sides), null=null)

    def null_material(self):
        """The material of index-matched (null BSDF) surfaces: they never scatter (cl/render/media.h)."""
        if self._null_material is None:
            from ..model import Material

            self._null_material = Material(name="mitsuba-null", albedo=(0.0, 0.0, 0.0))
        return self._null_material

    def shape(self, obj: MiObject) -> None:
        bsdfs = obj.children_of("bsdf")
        interface = self.interface(obj, bsdfs)
        emitters = obj.children_of("emitter")
        # Mitsuba's shape without a BSDF: diffuse, reflectance 0.5, or 0 for an emitter (shape.cpp)
        emitting = any(em.type in SURFACE_EMITTERS for em in emitters)
        emitter = -1  # our index of its area emitter (Scene.face_emitters), with its sampling_weight
        attribute = None
        if interface is not None and interface.null:  # index-matched: no scattering (scene/media.py)
            material = self.null_material()
            self.unused(bsdfs[0])
        else:
            material = self.bsdfs.material(bsdfs[0]) if bsdfs else self.bsdfs.default(black=emitting)
            attribute = self.bsdfs.attribute(material)  # a mesh_attribute as its reflectance
        if len(bsdfs) > 1:
            raise error_at(bsdfs[1].node.pos, f"{obj.label()}: a second BSDF is not supported (Mitsuba refuses it)")
        for em in emitters:
            if em.type not in SURFACE_EMITTERS:
                raise error_at(em.node.pos, f"{em.label()} in {obj.label()}: only area and directionalarea "
                                            "emitters attach to shapes")
            directional = em.type == "directionalarea"
            if directional and "to_world" in em.props:  # Mitsuba refuses it too
                raise error_at(em.props["to_world"].node.pos, f"{em.label()}: a directionalarea emitter takes "
                                                              "its shape's transform, not a to_world")
            radiance, texture = color_value(self, em, "radiance", (1.0, 1.0, 1.0), texture_ok=not directional)
            material = self.b.emissive(material, radiance, False, texture, directional=directional)
            if emitter < 0:
                emitter = self.b.new_emitter(sampling_weight(em))
            else:
                self.b.emitter_weights[emitter] = sampling_weight(em)
            self.unused(em)
        for extra in obj.children:
            if extra.tag not in ("bsdf", "emitter", "medium"):
                self.warn(extra.node.pos, f"{extra.label()} in {obj.label()}: not supported; ignored")
        flip = bool(obj.boolean("flip_normals", False))
        m = obj.transform("to_world")
        if m is not None and abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise error_at(obj.props["to_world"].node.pos, f"{obj.label()}: to_world is singular")
        t = obj.type
        if material.emission_directional and t in ("sphere", "cylinder"):  # (no plane to project onto)
            raise error_at(obj.node.pos, f"{obj.label()}: a directionalarea emitter on a curved shape is not "
                                         "supported (only on flat faces: meshes, rectangles, disks, cubes)")
        shape = MITSUBA_SHAPES.get(t)
        if shape is not None and not reads_uv(material) and not material.emission_directional and \
                self.analytic(obj, shape, material, m, flip, emitters, interface, emitter):
            return
        normals = compute = extras = None
        if t in ("obj", "ply", "serialized"):
            v, f, uv, normals, keys, extras = self.mesh_file(obj)
            if obj.boolean("face_normals", False):  # Mitsuba: flat, whatever the file holds
                normals = None
            elif normals is None:  # Mitsuba computes them
                compute = keys
        elif t == "sphere":  # its material reads the uv: Mitsuba's uv and exact normals (ours have no uv)
            v, f, uv, normals = mitsuba_sphere_mesh()
            local = np.diag([*[obj.float("radius", 1.0, positive=True)] * 3, 1.0])
            local[:3, 3] = obj.point("center", np.zeros(3))
            m = local if m is None else m @ local
        elif t == "rectangle":
            v, f, uv = rectangle_mesh()
        elif t == "cube":
            v, f, uv = mitsuba_cube_mesh()
        elif t == "disk":
            v, f, uv = mitsuba_disk_mesh()
        elif t == "cylinder":
            v, f, uv, normals = self.cylinder(obj)
        elif t == "sdfgrid":
            v, f, uv, normals = self.sdfgrid(obj, emitters)
        else:
            raise error_at(obj.node.pos, refusal(obj))
        if material.emission_directional and (normals is not None or compute is not None) and not flat(v, f):
            # Mitsuba's directionalarea emits along the interpolated vertex normal; ours along the face's
            raise error_at(obj.node.pos, f"{obj.label()}: a directionalarea emitter on a curved mesh with vertex "
                                         "normals is not supported (flat meshes, or face_normals true)")
        colors = None
        if attribute is not None:
            colors = extras.colors(attribute) if extras is not None else None
            if colors is None:
                self.warn(obj.node.pos, f'{obj.label()}: its BSDF reads the mesh attribute "{attribute}", which '
                                        "the shape does not have; using 1")
        self.b.add_mesh(v, f, material, uvs=uv, matrix=m, flip=flip, normals=normals, colors=colors,
                        compute_normals=compute, interface=interface, emitter=emitter)
        self.unused(obj)

    def cylinder(self, obj: MiObject):
        """Mitsuba's cylinder (src/shapes/cylinder.cpp): an open tube from p0 to p1, its uv (phi / 2 pi,
        the height's fraction) with phi from the first axis of Mitsuba's frame about p1 - p0
        (coordinate_system: +x for the default +z axis), shaded with its exact radial normal."""
        p0 = obj.point("p0", np.zeros(3))
        p1 = obj.point("p1", np.array([0.0, 0.0, 1.0]))
        radius = obj.float("radius", 1.0, positive=True)
        axis = p1 - p0
        length = float(np.linalg.norm(axis))
        if not length > 0:
            raise error_at(obj.node.pos, f"{obj.label()}: p0 and p1 are the same point")
        v, f, uv = cylinder_mesh(radius, 0.0, length, n_full=CURVED_SEGMENTS)
        z = axis / length
        x, y = coordinate_system(z)
        frame = np.stack([x, y, z], 1)
        radial = v * [1.0, 1.0, 0.0]  # Mitsuba's cylinder shades with its exact (radial) normal
        radial /= np.linalg.norm(radial, axis=1, keepdims=True)
        return v @ frame.T + p0, f, uv, (radial @ frame.T)[f]

    def sdfgrid(self, obj: MiObject, emitters):
        """Mitsuba's sdfgrid: the zero level set of its .vol grid of signed distances over the unit
        cube, as triangles with the field's gradient as their shading normals (loaders/sdfgrid.py;
        ``normals`` smooth or analytic alike).  Mitsuba refuses it as an area emitter, and so do we."""
        from .mitsuba_vol import read_vol
        from .sdfgrid import sdf_mesh

        if emitters:
            raise error_at(emitters[0].node.pos, f"{obj.label()}: an sdfgrid cannot be an area emitter (as in Mitsuba)")
        fname = obj.string("filename")
        if fname is None:
            raise error_at(obj.node.pos, f'{obj.label()} needs <string name="filename"> (a .vol grid)')
        obj.choice("normals", ("smooth", "analytic"))  # both: the field's gradient at the vertices, interpolated
        data, _box = read_vol(self.resolve(fname, obj), f"{obj.node.pos}: {obj.label()}")
        if data.shape[-1] != 1:
            raise error_at(obj.node.pos, f"{obj.label()}: '{fname}' has {data.shape[-1]} channels; an SDF grid has one")
        v, f, normals = sdf_mesh(data[..., 0])
        if not len(f):
            raise error_at(obj.node.pos, f"{obj.label()}: '{fname}' has no zero crossing: no surface (Mitsuba refuses "
                                         "a grid without one too)")
        return v, f, None, normals

    def analytic(self, obj, shape, material, m, flip, emitters, interface=None, emitter: int = -1) -> bool:
        """One of our analytic shapes (scene/shapes/: Mitsuba's sphere, disk), read by its type; a
        shape whose material reads the uv or dp/du (a texture, a normal or bump map, anisotropy) is
        Mitsuba's triangles with its uv instead (reads_uv), for ours have none.  A type that does not
        flip (a sphere faces outwards) gets its medium interface's sides swapped for flip_normals.
        False: the file's shape is not one of ours (an elliptic tube), the caller makes triangles."""
        pos = obj.props["to_world"].node.pos if "to_world" in obj.props else obj.node.pos
        p = shape.from_mitsuba(obj, ShapeMitsubaReading(m, flip, lambda what: self.warn(pos, f"{obj.label()}: {what}"),
                                                        lambda what: error_at(obj.node.pos, f"{obj.label()}: {what}")))
        if p is None:
            return False
        if flip and not shape.flips:
            if emitters:
                self.warn(obj.node.pos, f"{obj.label()}: flip_normals: our {shape.name}s emit outwards only")
            if interface is not None:  # its normal points inwards: interior and exterior trade places
                interface = interface.flipped()
        self.b.add_shape(shape, p, material, interface=interface, emitter=emitter)
        self.unused(obj)
        return True

    def mesh_file(self, obj: MiObject):
        """(vertices, faces, per-corner uvs, normals (or None) and the keys of the corners that
        are one vertex (Mitsuba's OBJ reader: one per position and texture coordinate), and the
        file's attributes (MeshExtras))."""
        from .meshfile import MeshExtras
        from .obj import parse_obj

        fname = obj.string("filename")
        if fname is None:
            raise error_at(obj.node.pos, f'{obj.label()} needs <string name="filename">')
        path = self.resolve(fname, obj)
        where = f"{obj.node.pos}: {obj.label()}: {fname}"
        extras = MeshExtras()
        if obj.type == "obj":
            v, f, _names, _libs, uv, normals = parse_obj(path, where, with_uvs=True, with_normals=True)
            keys = f
            if uv is not None:
                corners = np.concatenate([f.reshape(-1, 1).astype(np.float64), uv.reshape(-1, 2)], 1)
                keys = np.unique(corners, axis=0, return_inverse=True)[1].reshape(-1, 3)
                if not obj.boolean("flip_tex_coords", True):
                    uv[..., 1] = 1.0 - uv[..., 1]
        elif obj.type == "ply":
            v, f, uv, extras = _read_ply(path, where)
            normals, keys = extras.normals, f
        else:
            from .mitsuba_serialized import read_serialized

            v, f, uv, normals = read_serialized(path, obj.integer("shape_index", 0, minimum=0), where)
            keys = f
        if len(f) == 0:
            raise error_at(obj.node.pos, f"{obj.label()}: '{fname}' contains no triangles")
        return v, f, uv, normals, keys, extras

    # -- emitters --------------------------------------------------------------------------------

    def emitter(self, obj: MiObject) -> None:
        t = obj.type
        m = obj.transform("to_world")
        if t in MITSUBA_LIGHTS:  # a registered light type reads its own (scene/lights/)
            self.b.add_light(MITSUBA_LIGHTS[t].from_mitsuba(obj, EmitterReading(self, obj, m)))
        elif t == "constant":
            radiance, _ = color_value(self, obj, "radiance", (1.0, 1.0, 1.0))
            self.b.set_environment(Environment(radiance=radiance, sampling_weight=sampling_weight(obj)), obj.node.pos)
        elif t == "envmap":
            self.envmap(obj, m)
        elif t in SURFACE_EMITTERS:  # Mitsuba too: an area emitter needs a shape
            raise error_at(obj.node.pos, f"{obj.label()}: an area emitter must be attached to a shape")
        else:
            raise error_at(obj.node.pos, refusal(obj))
        self.unused(obj)

    def envmap(self, obj: MiObject, m) -> None:
        from .images import read_hdr_image

        fname = obj.string("filename")
        if fname is None:
            raise error_at(obj.node.pos, f'{obj.label()} needs <string name="filename">')
        image = read_hdr_image(self.resolve(fname, obj), f"{obj.node.pos}: {obj.label()}")
        s = obj.float("scale", 1.0, minimum=0.0)
        rot = np.eye(3) if m is None else m[:3, :3]
        h, w = image.shape[:2]
        self.b.set_environment(EnvMap(image=image, lookup=_mitsuba_env_uv, to_world=rot, scale=(s, s, s),
                                      source=str(fname), out_shape=(h, w), rows="poles",
                                      sampling_weight=sampling_weight(obj)), obj.node.pos)


class EmitterReading:
    """What a light type's ``from_mitsuba`` reads of an emitter besides its own numbers
    (scene/lights/__init__.py): colours and textures, its to_world (4x4 or None) as a position and
    a frame, a field of view, its sampling_weight, and errors at its place in the file."""

    def __init__(self, loader, obj: MiObject, to_world):
        self.loader, self.obj, self.to_world = loader, obj, to_world
        self.sampling_weight = sampling_weight(obj)

    def color(self, name, default, texture_ok=False):
        return color_value(self.loader, self.obj, name, default, texture_ok=texture_ok)

    def placed(self) -> tuple:
        """(position, 3x3 local-to-world) of a spot's or projector's to_world (None: the identity)."""
        m = self.to_world
        if m is None:
            return (0.0, 0.0, 0.0), None
        if abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise error_at(self.obj.props["to_world"].node.pos, f"{self.obj.label()}: to_world is singular")
        return tuple(map(float, m[:3, 3])), m[:3, :3].copy()

    def fov_x(self, aspect: float) -> float:
        return _mitsuba_fov_x(self.obj, aspect)

    def error(self, what: str):
        return error_at(self.obj.node.pos, f"{self.obj.label()}: {what}")


def sampling_weight(emitter: MiObject) -> float:
    """An emitter's sampling_weight (emitter.cpp: default 1): its share of the light picks."""
    return emitter.float("sampling_weight", 1.0, minimum=0.0)


def _mitsuba_env_uv(d):
    """Mitsuba's envmap: u = atan2(x, -z) / 2 pi, v = acos(y) / pi."""
    u = np.arctan2(d[:, 0], -d[:, 2]) / (2 * np.pi)
    v = np.arccos(np.clip(d[:, 1], -1.0, 1.0)) / np.pi
    return np.mod(u, 1.0), v


def _read_ply(path, where):
    from ..mesh import MeshError, flatten, load_trimesh

    try:
        loaded = load_trimesh(path)
        v, f = flatten(loaded, name=where)
    except MeshError as exc:
        raise error_at(where.split(": ")[0], str(exc)) from None
    from .meshfile import ply_extras

    uv = getattr(getattr(loaded, "visual", None), "uv", None)
    uvc = None
    if uv is not None and len(uv) == len(v) and len(loaded.faces) == len(f):
        uvc = np.asarray(uv, np.float32)[np.asarray(f)][..., :2]  # Mitsuba reads PLY uvs as they are
    return v, f, uvc, ply_extras(loaded, f)


def _mitsuba_fov(obj: MiObject) -> tuple[float, str]:
    """(fov [degrees], its axis: x, y, diagonal, smaller or larger) of a sensor-like plugin's fov /
    fov_axis or focal_length (a 35 mm film's diagonal), checked (Mitsuba's parse_fov,
    src/render/sensor.cpp)."""
    if obj.has("fov") and obj.has("focal_length"):
        raise error_at(obj.node.pos, f"{obj.label()}: give fov or focal_length, not both")
    if obj.has("fov"):
        fov = obj.float("fov", positive=True)
        axis = obj.string("fov_axis", "x").lower()
        if axis not in ("x", "y", "diagonal", "smaller", "larger"):
            raise error_at(obj.props["fov_axis"].node.pos,
                           f"{obj.label()}: unknown fov_axis '{axis}' (x, y, diagonal, smaller, larger)")
    else:
        text = obj.string("focal_length", "50mm")
        try:
            f = float(text[:-2] if text.endswith("mm") else text)
        except ValueError:
            raise error_at(obj.props["focal_length"].node.pos,
                           f"{obj.label()}: focal_length must look like '35mm', got '{text}'") from None
        fov, axis = float(np.degrees(2 * np.arctan(np.hypot(36.0, 24.0) / (2 * f)))), "diagonal"
    if not 0 < fov < 180:
        raise error_at(obj.node.pos, f"{obj.label()}: fov must be between 0 and 180 degrees, got {fov:g}")
    return fov, axis


def _mitsuba_fov_x(obj: MiObject, aspect: float) -> float:
    """The field of view along x [degrees] of a sensor-like plugin for an image of width / height
    ``aspect``."""
    fov, axis = _mitsuba_fov(obj)
    if axis == "smaller":
        axis = "y" if aspect > 1 else "x"
    elif axis == "larger":
        axis = "x" if aspect > 1 else "y"
    half = np.tan(np.radians(fov) / 2)
    if axis == "y":
        half *= aspect
    elif axis == "diagonal":
        half /= np.sqrt(1.0 + 1.0 / (aspect * aspect))
    return float(np.degrees(2 * np.arctan(half)))
