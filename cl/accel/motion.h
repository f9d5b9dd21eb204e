/* A moving thing's way between two transforms (motion blur, abi.MOTION; pyopencl_rt/accel/motion.py
 * is the same in float64): M(s) = Cw^-1 T(s) R(s) S(s) Co, T and S interpolated linearly between the
 * ends, R by slerp, seen from a pivot (Co, Cw: its moves to the origin in the thing's space and in
 * the world).  Moving instances (cl/accel/instances.h) and a moving camera (cl/render/path.h
 * camera_ray) read it at a ray's time sample u: s = clamp(a + b u, 0, 1) (Scene.motion_time). */
#ifndef PYOPENCL_RT_MOTION_H
#define PYOPENCL_RT_MOTION_H

#include "common.h"

/* m (3x4 rows: M(s), the moving thing's space to the world) and w (its inverse) of the way `mo` at s
 * in [0, 1] of the way */
RT_INLINE void motion_matrices_at(__global const Motion *mo, float s, float *m, float *w)
{
    const float theta = mo->time[2];
    const float c0 = theta > 1e-6f ? sin((1.0f - s) * theta) / mo->time[3] : 1.0f - s;
    const float c1 = theta > 1e-6f ? sin(s * theta) / mo->time[3] : s;
    float4 q = c0 * vload4(0, mo->q0) + c1 * vload4(0, mo->q1);
    q *= 1.0f / sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w); /* unit up to rounding: made so */
    const float r[9] = {1.0f - 2.0f * (q.y * q.y + q.z * q.z), 2.0f * (q.x * q.y - q.z * q.w),
                        2.0f * (q.x * q.z + q.y * q.w), 2.0f * (q.x * q.y + q.z * q.w),
                        1.0f - 2.0f * (q.x * q.x + q.z * q.z), 2.0f * (q.y * q.z - q.x * q.w),
                        2.0f * (q.x * q.z - q.y * q.w), 2.0f * (q.y * q.z + q.x * q.w),
                        1.0f - 2.0f * (q.x * q.x + q.y * q.y)};
    float a[9]; /* R S */
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            float v = 0.0f;
            for (int k = 0; k < 3; ++k) v += r[3 * i + k] * ((1.0f - s) * mo->s0[4 * k + j] + s * mo->s1[4 * k + j]);
            a[3 * i + j] = v;
        }
    /* T, then the pivot (co in the instance's space, cw in the world): M x = (T R S)(x - co) + cw */
    const float3 co = vload3(0, mo->pivot);
    const float3 t = (1.0f - s) * vload3(0, mo->t0) + s * vload3(0, mo->t1) + vload3(0, mo->world_pivot) -
                     (float3)(a[0] * co.x + a[1] * co.y + a[2] * co.z, a[3] * co.x + a[4] * co.y + a[5] * co.z,
                              a[6] * co.x + a[7] * co.y + a[8] * co.z);
    /* the inverse by the adjugate */
    const float c[9] = {a[4] * a[8] - a[5] * a[7], a[2] * a[7] - a[1] * a[8], a[1] * a[5] - a[2] * a[4],
                        a[5] * a[6] - a[3] * a[8], a[0] * a[8] - a[2] * a[6], a[2] * a[3] - a[0] * a[5],
                        a[3] * a[7] - a[4] * a[6], a[1] * a[6] - a[0] * a[7], a[0] * a[4] - a[1] * a[3]};
    const float inv_det = 1.0f / (a[0] * c[0] + a[1] * c[3] + a[2] * c[6]);
    const float tt[3] = {t.x, t.y, t.z};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            m[4 * i + j] = a[3 * i + j];
            w[4 * i + j] = c[3 * i + j] * inv_det;
        }
        m[4 * i + 3] = tt[i];
    }
    for (int i = 0; i < 3; ++i) w[4 * i + 3] = -(w[4 * i] * tt[0] + w[4 * i + 1] * tt[1] + w[4 * i + 2] * tt[2]);
}

/* a 3x4 matrix (rows) times a point */
RT_INLINE float3 xf_point_private(const float *m, float3 p)
{
    return (float3)(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                    m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]);
}

/* the 3x3 part of a 3x4 matrix (rows) times a vector */
RT_INLINE float3 xf_vector_private(const float *m, float3 v)
{
    return (float3)(m[0] * v.x + m[1] * v.y + m[2] * v.z, m[4] * v.x + m[5] * v.y + m[6] * v.z,
                    m[8] * v.x + m[9] * v.y + m[10] * v.z);
}

/* the same at a ray's time sample u */
RT_INLINE void motion_matrices(__global const Motion *mo, float u, float *m, float *w)
{
    motion_matrices_at(mo, clamp(mo->time[0] + mo->time[1] * u, 0.0f, 1.0f), m, w);
}

#endif
