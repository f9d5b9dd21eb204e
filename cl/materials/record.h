/* A material record over the lanes: the fields of the lanes' abi.MATERIAL records gathered into
 * MaterialLanes (material_lanes), and what several types read from them (their microfacet
 * distribution, the relative index of refraction).  Each type's header (cl/materials/<name>.h) makes
 * its own parameters from a MaterialLanes; cl/materials/dispatch.h routes the calls.
 *
 * The Mitsuba types (plastic, roughplastic, principled, principledthin) read the Material fields
 * after the texture indices; material_lanes() gathers those only when some lane has such a type.
 * roughplastic reads its table from the records themselves (MaterialLanes.records/rec). */
#ifndef PYOPENCL_RT_RECORD_H
#define PYOPENCL_RT_RECORD_H

#include "materials/microfacet.h"

#if defined(HAS_MATERIAL_PLASTIC) || defined(HAS_MATERIAL_ROUGHPLASTIC) || defined(HAS_MATERIAL_PRINCIPLED) || \
    defined(HAS_MATERIAL_PRINCIPLEDTHIN)
#define HAS_MITSUBA_MATERIALS /* the Material fields after the texture indices are used */
#endif

/* The Material records' fields, per lane.  The fields of the Mitsuba types (fdr to rates) are
 * gathered only when some lane has such a type (else 0). */
typedef struct {
    pint type, flags;
    pvec3 albedo, emission, specular, eta, k;
    pfloat alpha, alpha_v, metallic, ior;
    pint tex_base, tex_mr, tex_emission; /* texture indices, -1 none */
    pfloat opacity; /* MATERIAL_FLAG_MASK: the record's opacity (times its texture, cl/scene/textures.h); else 1 */
    pfloat fdr, spec_weight, roughness, anisotropic, spec_trans, spec_tint, sheen, sheen_tint, clearcoat,
        clearcoat_gloss, flatness, diff_trans, rate0, rate1, rate2, rate3;
    __global const float *records; /* the Material array as floats, and each lane's record in it */
    pint rec;
} MaterialLanes;

/* materials[index] in each lane (index valid in every lane) */
RT_INLINE MaterialLanes material_lanes(__global const Material *materials, pint index)
{
    const pint i = index * STRIDE_INDEX(Material); /* the lanes' records, as float indices */
    __global const float *f = (__global const float *)materials;
    MaterialLanes m;
    /* m.x = the lanes' field x of their records */
#define GATHER_INT(x) m.x = pgather_int((__global const int *)materials, i + FIELD_INDEX(Material, x));
#define GATHER_VEC3(x) m.x = pv3_gather(f, i + FIELD_INDEX(Material, x));
#define GATHER_FLOAT(x) m.x = pgather(f, i + FIELD_INDEX(Material, x));
    GATHER_INT(type) GATHER_INT(flags) GATHER_INT(tex_base) GATHER_INT(tex_mr) GATHER_INT(tex_emission)
    GATHER_VEC3(albedo) GATHER_VEC3(emission) GATHER_VEC3(specular) GATHER_VEC3(eta) GATHER_VEC3(k)
    GATHER_FLOAT(alpha) GATHER_FLOAT(alpha_v) GATHER_FLOAT(metallic) GATHER_FLOAT(ior)
    m.records = f;
    m.rec = i;
    m.opacity = PFLOAT(1.0f);
    const pint masked = (m.flags & MATERIAL_FLAG_MASK) != 0;
    if (pany(masked)) m.opacity = masked ? pgather(f, i + FIELD_INDEX(Material, opacity)) : m.opacity;
    m.fdr = m.spec_weight = m.roughness = m.anisotropic = m.spec_trans = m.spec_tint = m.sheen = m.sheen_tint =
        m.clearcoat = m.clearcoat_gloss = m.flatness = m.diff_trans = m.rate0 = m.rate1 = m.rate2 = m.rate3 =
            PFLOAT(0.0f);
#ifdef HAS_MITSUBA_MATERIALS
    if (pany((m.type >= MATERIAL_PLASTIC) & (m.type <= MATERIAL_PRINCIPLEDTHIN))) { /* plastic .. principledthin */
        GATHER_FLOAT(fdr) GATHER_FLOAT(spec_weight) GATHER_FLOAT(roughness) GATHER_FLOAT(anisotropic)
        GATHER_FLOAT(spec_trans) GATHER_FLOAT(spec_tint) GATHER_FLOAT(sheen) GATHER_FLOAT(sheen_tint)
        GATHER_FLOAT(clearcoat) GATHER_FLOAT(clearcoat_gloss) GATHER_FLOAT(flatness) GATHER_FLOAT(diff_trans)
        m.rate0 = pgather(f, i + FIELD_INDEX(Material, rates));
        m.rate1 = pgather(f, i + FIELD_INDEX(Material, rates) + 1);
        m.rate2 = pgather(f, i + FIELD_INDEX(Material, rates) + 2);
        m.rate3 = pgather(f, i + FIELD_INDEX(Material, rates) + 3);
    }
#endif
#undef GATHER_INT
#undef GATHER_VEC3
#undef GATHER_FLOAT
    return m;
}

/* The microfacet distribution of a conductor or dielectric (microfacet.h): alpha (alpha_u) and,
 * with MATERIAL_FLAG_ANISOTROPIC, alpha_v; *smooth: the lanes whose alphas are all below the
 * smooth threshold (a delta lobe). */
RT_INLINE Microfacet microfacet_params(const MaterialLanes *m, pint *smooth)
{
    const pfloat ay = (m->flags & MATERIAL_FLAG_ANISOTROPIC) != 0 ? m->alpha_v : m->alpha;
    *smooth = microfacet_is_smooth(m->alpha) & microfacet_is_smooth(ay);
    const Microfacet d = {.ax = pfmax(m->alpha, PFLOAT(1e-4f)), .ay = pfmax(ay, PFLOAT(1e-4f)),
                          .beckmann = (m->flags & MATERIAL_FLAG_BECKMANN) != 0,
                          .separable = (m->flags & MATERIAL_FLAG_SEPARABLE) != 0};
    return d;
}

/* the lanes whose microfacet distribution is smooth (a delta lobe) */
RT_INLINE pint material_smooth(const MaterialLanes *m)
{
    pint smooth;
    (void)microfacet_params(m, &smooth);
    return smooth;
}

/* The relative index eta = eta_t / eta_i seen by wo (dispatch.h's interface): ior on the front side,
 * 1 / ior behind it; 1 for ior <= 0, thin dielectrics, and a thin sheet (principledthin), which does
 * not bend light. */
RT_INLINE pfloat dielectric_eta(const MaterialLanes *m, pint front)
{
    const pfloat ior = ((m->ior > 0.0f) & (m->type != MATERIAL_PRINCIPLEDTHIN) & ((m->flags & MATERIAL_FLAG_THIN) == 0))
                           ? m->ior : PFLOAT(1.0f);
    return front ? ior : 1.0f / ior;
}

#endif
