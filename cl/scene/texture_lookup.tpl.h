/* The image-texture lookup (textures.h documents it), written once over a value type and expanded
 * twice (the host expands a .tpl.h at every include; pyopencl_rt/device/kernels.py): with
 * TL_LANES 0 for one lookup (float, int: the traversal's cut-out tests and the callers that run
 * lane by lane), and with TL_LANES 1 over the lanes of cl/render/lanes.h (pfloat, pint: the lanes
 * that read one texture, whose record is then the same in all of them).  The arithmetic is the
 * same in both, in the same order, so a lane's texel is the one lookup's, bit for bit.  Names
 * carry the kind: TL_(tex_coord) is tex_coord1 or tex_coord_lanes. */
#if TL_LANES
#define TL_F pfloat
#define TL_I pint
#define TL_(name) name##_lanes
#define TL_FLOOR(x) pfloor(x)
#define TL_FINITE(x) pisfinite(x)
#define TL_MIN(a, b) pfmin(a, b)
#define TL_MAX(a, b) pfmax(a, b)
#define TL_TO_INT(x) convert_pint(x)
#define TL_FETCH(texels, i) pgather(texels, i)
#else
#define TL_F float
#define TL_I int
#define TL_(name) name##1
#define TL_FLOOR(x) floor(x)
#define TL_FINITE(x) isfinite(x)
#define TL_MIN(a, b) fmin(a, b)
#define TL_MAX(a, b) fmax(a, b)
#define TL_TO_INT(x) ((int)(x))
#define TL_FETCH(texels, i) (texels)[i]
#endif

/* A texel index wrapped into [0, n) by the record's mode; i lies in [-1, 2n] for repeat and
 * mirror (the coordinate was reduced to one period), anywhere for clamp. */
RT_INLINE TL_I TL_(tex_wrap)(TL_I i, int n, int wrap)
{
    if (wrap == TEXTURE_WRAP_CLAMP) return i < 0 ? (TL_I)(0) : (i > n - 1 ? (TL_I)(n - 1) : i);
    if (wrap == TEXTURE_WRAP_MIRROR) {
        const TL_I m = i < 0 ? i + 2 * n : (i >= 2 * n ? i - 2 * n : i);
        return m >= n ? 2 * n - 1 - m : m;
    }
    return i < 0 ? i + n : (i >= n ? i - n : i);
}

/* One coordinate in texels of a lookup (before the half-texel shift): c reduced to one period
 * (repeat: [0, 1), mirror: [0, 2)) or, for clamp, to [-1, 2] (beyond that every texel index clamps
 * the same way), times n; a non-finite c reads as 0. */
RT_INLINE TL_F TL_(tex_coord)(TL_F c, int n, int wrap)
{
    c = TL_FINITE(c) ? c : (TL_F)(0.0f);
    if (wrap == TEXTURE_WRAP_CLAMP) c = TL_MIN(TL_MAX(c, (TL_F)(-1.0f)), (TL_F)(2.0f));
    else if (wrap == TEXTURE_WRAP_MIRROR) c -= 2.0f * TL_FLOOR(0.5f * c);
    else c -= TL_FLOOR(c);
    return c * (float)n;
}

/* The texels a lookup of record t at (u, v) reads, as float indices into its texels (4 floats a
 * texel): i00 (the top-left one) ... i11; for a bilinear lookup ax, ay are the weights of the
 * right and bottom ones; a nearest lookup has all four the same and weights 0. */
typedef struct {
    TL_I i00, i10, i01, i11;
    TL_F ax, ay;
    int nearest; /* the record's filter is nearest: i00 is the texel */
} TL_(TexelQuad);

RT_INLINE TL_(TexelQuad) TL_(tex_quad)(__global const Texture *t, TL_F u, TL_F v)
{
    const int w = t->width, h = t->height, wrap = t->wrap;
    /* uv through the record's affine to_uv (non-finite parts read as 0) */
    u = TL_FINITE(u) ? u : (TL_F)(0.0f);
    v = TL_FINITE(v) ? v : (TL_F)(0.0f);
    const TL_F cu = t->to_uv[0] * u + t->to_uv[1] * v + t->to_uv[2];
    const TL_F cv = t->to_uv[3] * u + t->to_uv[4] * v + t->to_uv[5];
    TL_(TexelQuad) q;
    q.nearest = t->filter == TEXTURE_FILTER_NEAREST;
    if (q.nearest) {
        const TL_I x = TL_(tex_wrap)(TL_TO_INT(TL_FLOOR(TL_(tex_coord)(cu, w, wrap))), w, wrap);
        const TL_I y = TL_(tex_wrap)(TL_TO_INT(TL_FLOOR(TL_(tex_coord)(cv, h, wrap))), h, wrap);
        q.i00 = q.i10 = q.i01 = q.i11 = 4 * (y * w + x);
        q.ax = q.ay = (TL_F)(0.0f);
        return q;
    }
    const TL_F fx = TL_(tex_coord)(cu, w, wrap) - 0.5f, fy = TL_(tex_coord)(cv, h, wrap) - 0.5f;
    const TL_F x0f = TL_FLOOR(fx), y0f = TL_FLOOR(fy);
    q.ax = fx - x0f;
    q.ay = fy - y0f;
    const TL_I x0 = TL_TO_INT(x0f), y0 = TL_TO_INT(y0f);
    const TL_I x = TL_(tex_wrap)(x0, w, wrap), y = TL_(tex_wrap)(y0, h, wrap);
    const TL_I x1 = TL_(tex_wrap)(x0 + 1, w, wrap), y1 = TL_(tex_wrap)(y0 + 1, h, wrap);
    q.i00 = 4 * (y * w + x);
    q.i10 = 4 * (y * w + x1);
    q.i01 = 4 * (y1 * w + x);
    q.i11 = 4 * (y1 * w + x1);
    return q;
}

/* Channel c of the lookup q over `texels` (the record's first texel): the texel, or bilinear: the
 * top row then the bottom row, each a + (b - a) s. */
RT_INLINE TL_F TL_(tex_channel)(__global const float *texels, const TL_(TexelQuad) *q, int c)
{
    if (q->nearest) return TL_FETCH(texels, q->i00 + c);
    const TL_F a = TL_FETCH(texels, q->i00 + c), b = TL_FETCH(texels, q->i10 + c);
    const TL_F d = TL_FETCH(texels, q->i01 + c), e = TL_FETCH(texels, q->i11 + c);
    const TL_F top = a + (b - a) * q->ax, bottom = d + (e - d) * q->ax;
    return top + (bottom - top) * q->ay;
}

/* The gradient (d/du, d/dv) of a bilinear lookup's luminance (Rec. 709 weights), as Mitsuba 3's
 * bitmap texture computes it for bump maps (eval_1_grad): the derivative of the bilinear
 * interpolation within the four texels q reads, times the resolution, taken back through to_uv
 * (its transpose, then the resolution, in Mitsuba's order).  A nearest lookup has none (the
 * caller's 0). */
#define TL_LUM(i) (TL_FETCH(texels, (i)) * 0.212671f + TL_FETCH(texels, (i) + 1) * 0.715160f + \
                   TL_FETCH(texels, (i) + 2) * 0.072169f)
RT_INLINE void TL_(tex_gradient_of)(__global const Texture *t, __global const float *texels, const TL_(TexelQuad) *q,
                                 TL_F *gu, TL_F *gv)
{
    const TL_F f00 = TL_LUM(q->i00), f10 = TL_LUM(q->i10), f01 = TL_LUM(q->i01), f11 = TL_LUM(q->i11);
    const TL_F dx = (1.0f - q->ay) * (f10 - f00) + q->ay * (f11 - f01);
    const TL_F dy = (1.0f - q->ax) * (f01 - f00) + q->ax * (f11 - f10);
    *gu = (float)t->width * (t->to_uv[0] * dx + t->to_uv[3] * dy);
    *gv = (float)t->height * (t->to_uv[1] * dx + t->to_uv[4] * dy);
}
#undef TL_LUM

#undef TL_F
#undef TL_I
#undef TL_
#undef TL_FLOOR
#undef TL_FINITE
#undef TL_MIN
#undef TL_MAX
#undef TL_TO_INT
#undef TL_FETCH
