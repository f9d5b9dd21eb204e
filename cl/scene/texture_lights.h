/* The emission textures of next-event estimation's light samples (compiled with HAS_TEXTURES, after
 * render/lights.h and scene/textures.h; cl/render/path.h includes it).  A file of its own: the host
 * includes each file once, and scene/scene.h may include textures.h from inside lights.h. */
#ifndef PYOPENCL_RT_TEXTURE_LIGHTS_H
#define PYOPENCL_RT_TEXTURE_LIGHTS_H

#include "render/lights.h"
#include "scene/textures.h"

/* After light_sample_all(..., light_index, sampled, ref, ux, uy, ls): the emission texture at the
 * sampled point of the lanes whose light is a textured emissive triangle, and a spot's or
 * projector's texture at the (u, v) it set (ls->tex, ls->tu, ls->tv). */
RT_INLINE void texture_light_emission(__global const float2 *tri_uv, __global const Texture *textures,
                                      __global const float4 *data, __global const Material *materials,
                                      __global const Light *lights, pint light_index, pint sampled, pfloat ux,
                                      pfloat uy, LightSample *ls)
{
    pfloat b1, b2;
    sample_triangle_barycentrics(ux, uy, &b1, &b2);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        if (!PLANE_I(sampled, k)) continue;
        if (PLANE_I(ls->tex, k) >= 0) { /* a spot's or projector's texture at its (u, v) */
            const float2 uv = (float2)(PLANE(ls->tu, k), PLANE(ls->tv, k));
            pv3_set_lane(&ls->Le, k, pv3_lane(ls->Le, k) * tex_sample(textures, data, PLANE_I(ls->tex, k), uv).xyz);
            continue;
        }
        __global const Light *light = lights + PLANE_I(light_index, k);
        __global const Material *m = materials + light->material;
        if (light->kind != LIGHT_TRIANGLE || m->tex_emission < 0) continue;
        const float2 uv = triangle_uv(tri_uv, light->prim, PLANE(b1, k), PLANE(b2, k));
        pv3_set_lane(&ls->Le, k, pv3_lane(ls->Le, k) * tex_sample(textures, data, m->tex_emission, uv).xyz);
    }
}

#endif
