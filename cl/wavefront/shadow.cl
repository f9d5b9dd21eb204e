/* Stage 4: any-hit test of every queued light sample; unoccluded ones add their contribution.
 * The shadow ray runs from the offset surface point to the offset light point, t in (0, 1).
 * With HAS_MEDIA it adds its contribution times the transmittance (shadow_transmittance of
 * cl/render/volpath.h, as the megakernel: through media and null surfaces, 0 where a surface
 * blocks it), drawing ratio tracking's numbers from the path's stream, which then goes on. */
#include "render/lights.h"
#ifdef HAS_MEDIA
#include "render/path.h"
#include "render/volpath.h"
#endif

__kernel void wf_shadow(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= counters[COUNTER_SHADOW]) return;
    const int slot = shadow_q[i];
#ifdef HAS_MEDIA
    puint rng = vol_rng[slot];
    const pvec3 tr = shadow_transmittance(nodes, tris, MESH_ARGS, face_normal, shape_nodes, shapes, tri_material, shape_material,
                                          materials, MEDIA_PATH_ARGS, pv3_from(load3(sh_o, slot)),
                                          pv3_from(load3(sh_d, slot)), sh_medium[slot], vol_channel[slot], &rng,
                                          pv3_from(load3(vol_r, slot)), PTRUE);
    vol_rng[slot] = rng;
    store3(radiance, slot,
           pv3_lane(pv3_add(pv3_from(load3(radiance, slot)), pv3_mul(pv3_from(load3(sh_contrib, slot)), tr)), 0));
#else
    if (!scene_occluded(nodes, tris, shape_nodes, shapes, pv3_from(load3(sh_o, slot)), pv3_from(load3(sh_d, slot)), PTRUE,
                        1.0f CUTOUT_ARGS INSTANCE_ARGS
                        SCENE_TIME_ARG(time_sample(sampler_key(sampler, seed, (uint)path_pixel[slot],
                                                                 (uint)camera->width, (uint)path_pass[slot])))))
        store3(radiance, slot, load3(radiance, slot) + load3(sh_contrib, slot));
#endif
}
