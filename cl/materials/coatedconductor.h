/* A conductor under a dielectric coating ("coatedconductor"): pbrt-v4's CoatedConductorBxDF, its
 * LayeredBxDF of a dielectric interface over a conductor with the light that scatters between the
 * two estimated by a random walk (Guo et al. 2018, "Position-Free Monte Carlo Simulation for
 * Arbitrary Layered BSDFs"; pbrt-v4, section 14.3).
 *
 * Parameters (Material fields):
 *   ior            the coating's index relative to the outside (pbrt's interface.eta)
 *   alpha, alpha_v the coating's microfacet roughness (alpha_v with MATERIAL_FLAG_ANISOTROPIC; smooth
 *                  below 1e-3, as conductor.h)
 *   eta, k         the conductor's complex index relative to the coating (pbrt divides conductor.eta
 *                  and conductor.k by interface.eta)
 *   table[0..8]    the layer (COATED_*): the conductor's alpha along the tangent and the bitangent, the
 *                  coating's thickness in mean free paths (light crossing it at cos theta keeps
 *                  exp(-thickness / |cos|)), the walk's maximum depth and its number of samples (pbrt's
 *                  maxdepth, nsamples), the coating's single-scattering albedo (rgb) and its
 *                  Henyey-Greenstein asymmetry g (pbrt's albedo, g)
 *
 * Two-sided, reflection only, and every quantity is an estimate, as in pbrt-v4:
 *   eval    f(wo, wi): the coating's own reflection, plus walks that refract in towards wo, bounce
 *           between the conductor and the coating's underside (Russian roulette after depth 3,
 *           maxdepth steps at most), and connect at each conductor bounce to wi's refracted direction
 *           and, through a rough coating, out towards wi (the two power-heuristic weighted)
 *   pdf     0.1 / (4 pi) plus 0.9 times an estimate of the density: the coating's reflection, and the
 *           conductor's density between the refracted directions (MIS-weighted through a rough coating)
 *   sample  the coating's sample; a refracted one walks on until it leaves through the coating, with
 *           the walk's weight (the product of f cos over the product of densities); MIS takes the
 *           estimated pdf (pbrt's pdfIsProportional).  A walk of smooth interfaces only is a delta sample.
 * The estimates draw their random numbers from a hash of their directions (and of the sample's u), as
 * pbrt's RNG(Hash(wo), Hash(wi)): each is a function of its arguments, the same at every lane width.
 * The coating's inner dielectric interface transports radiance (f / eta'^2 refracted) towards wo and
 * importance (no eta'^2) from wi, as pbrt-v4's TransportMode; the conductor is conductor.h's.
 * A scattering coating (albedo > 0 in a channel) is a medium of unit extinction between the layers, as
 * pbrt-v4's: the walk tracks its height z (the coating at thickness, the metal at 0), samples a free
 * path, and where it stops inside scatters by the phase function (weight albedo); f then also connects
 * each scattering point to wi's refracted direction and, through a rough coating, out towards wi.  pbrt's
 * PDF estimate leaves the medium out, and so does coated_pdf.  Each lane draws from its own counter, so
 * that lanes at different heights (or of different materials) keep the stream they have at width 1.
 */
#ifndef PYOPENCL_RT_COATEDCONDUCTOR_H
#define PYOPENCL_RT_COATEDCONDUCTOR_H

#include "materials/conductor.h"
#include "materials/microfacet.h"
#include "materials/record.h"
#include "render/phase.h"
#include "render/rng.h"

/* f's estimate of the light that leaves the conductor: 0 both connections, power-heuristic weighted as
 * pbrt-v4 weights them; 1 only towards wi's refracted direction, 2 only out through the coating from the
 * conductor's sample (each alone an unbiased estimate: tests/scene/test_coatedconductor.py) */
#ifndef COATED_NEE
#define COATED_NEE 0
#endif

typedef struct {
    Microfacet coat;
    pint coat_smooth;
    pfloat eta;          /* the coating's index relative to the outside */
    ConductorParams metal; /* under the coating: eta, k relative to it */
    pfloat thickness;
    pint max_depth, samples;
    pvec3 albedo;        /* the coating's single-scattering albedo (0: a clear, absorbing coating) */
    pfloat g;            /* its phase function's asymmetry */
    pint scattering;     /* albedo > 0 in some channel */
} CoatedConductorParams;

/* A sample of the coating (pbrt's BSDFSample): f without the cosine, its density, and masks */
typedef struct {
    pvec3 wi;
    pfloat f, pdf;
    pint ok, specular, transmitted;
} CoatSample;

/* The walk's random numbers: the n-th of a stream keyed by a hash of directions (n per lane) */
typedef struct {
    puint key;
    puint n;
} CoatRng;

RT_INLINE puint coat_hash3(puint h, pvec3 v)
{
    h = hash_u32(h ^ as_puint(v.x));
    h = hash_u32(h ^ as_puint(v.y));
    return hash_u32(h ^ as_puint(v.z));
}

RT_INLINE CoatRng coat_rng(uint stream, pvec3 a, pvec3 b)
{
    const CoatRng r = {coat_hash3(coat_hash3(PUINT(stream + RNG_KEY_OFFSET), a), b), PUINT(0u)};
    return r;
}

/* the next number of the lanes in `used` (the others' counters stay) */
RT_INLINE pfloat coat_next_in(CoatRng *r, pint used)
{
    const pfloat u = u32_to_unit_float(hash_u32(r->key ^ hash_u32(r->n + RNG_KEY_OFFSET)));
    r->n = used ? r->n + PUINT(1u) : r->n;
    return u;
}

RT_INLINE pfloat coat_next(CoatRng *r) { return coat_next_in(r, PINT(-1)); }

/* pbrt-v4's SampleExponential with sigma_t 1 along w: the height the walk climbs (or falls) before the
 * medium stops it */
RT_INLINE pfloat coat_free_height(pfloat u, pvec3 w) { return -plog(1.0f - u) * pabs(w.z); }

/* pbrt-v4's Tr: the share of light crossing a height dz of the coating (either way) along w */
RT_INLINE pfloat coat_tr(pfloat dz, pvec3 w)
{
    return pabs(dz) <= 1.17549435e-38f ? PFLOAT(1.0f) : pexp(-pabs(dz / w.z));
}

/* pbrt-v4's PowerHeuristic(1, a, 1, b) */
RT_INLINE pfloat coat_power(pfloat a, pfloat b)
{
    const pfloat a2 = a * a;
    return pisinf(a2) ? PFLOAT(1.0f) : a2 / (a2 + b * b);
}

/* the density of the coating's visible normal m for w on either side (sampled for w's upper image) */
RT_INLINE pfloat coat_vndf_pdf(const CoatedConductorParams *p, pvec3 w, pvec3 m)
{
    const pvec3 up = pv3_sel(w, pv3_neg(w), w.z < 0.0f);
    return mf_vndf_pdf(up, m, p->coat.ax, p->coat.ay, p->coat.beckmann);
}

/* The coating's f(wo, wi) (0 where smooth) and, in *pdf, the density of coat_sample with the lobes
 * allowed (reflection, transmission); wo and wi on either side; `radiance`: the transport mode. */
RT_INLINE pfloat coat_f(const CoatedConductorParams *p, pint active, pvec3 wo, pvec3 wi, int radiance, int allow_r,
                        int allow_t, pfloat *pdf)
{
    const pfloat cos_o = wo.z, cos_i = wi.z;
    const pint reflect = cos_i * cos_o > 0.0f;
    const pfloat etap = reflect ? PFLOAT(1.0f) : (cos_o > 0.0f ? p->eta : 1.0f / p->eta);
    pvec3 m = pv3_add(pv3_scale(wi, etap), wo);
    const pfloat len2 = pv3_dot(m, m);
    pint ok = active & pnot(p->coat_smooth) & (cos_i != 0.0f) & (cos_o != 0.0f) & (len2 > 0.0f);
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return PFLOAT(0.0f);
    m = pv3_scale(m, 1.0f / psqrt(ok ? len2 : PFLOAT(1.0f)));
    m = pv3_sel(m, pv3_neg(m), m.z < 0.0f);
    const pfloat mo = pv3_dot(wo, m), mi = pv3_dot(wi, m);
    ok &= pnot((mi * cos_i < 0.0f) | (mo * cos_o < 0.0f));
    const pfloat F = fresnel_dielectric(mo, p->eta), T = 1.0f - F;
    const pfloat D = mf_d(m, p->coat.ax, p->coat.ay, p->coat.beckmann), G = mf_g(&p->coat, wo, wi, m);
    const pfloat denom = (mi + mo / etap) * (mi + mo / etap);
    pfloat ft = T * D * G * pabs(mi * mo / (cos_i * cos_o * denom));
    if (radiance) ft = ft / (etap * etap);
    const pfloat f = reflect ? D * G * F / pabs(4.0f * cos_i * cos_o) : ft;
    const pfloat pr = allow_r ? F : PFLOAT(0.0f), pt = allow_t ? T : PFLOAT(0.0f);
    const pfloat pm = coat_vndf_pdf(p, wo, m);
    pfloat q = reflect ? pm / (4.0f * pabs(mo)) * (pr / (pr + pt)) : pm * pabs(mi) / denom * (pt / (pr + pt));
    ok &= pisfinite(f);
    q = (pr + pt > 0.0f) & pisfinite(q) ? q : PFLOAT(0.0f);
    *pdf = ok ? q : PFLOAT(0.0f);
    return ok ? f : PFLOAT(0.0f);
}

/* pbrt-v4's DielectricBxDF::Sample_f restricted to the lobes allowed: wo on either side; uc picks
 * reflection or refraction, (u0, u1) the microfacet normal. */
RT_INLINE CoatSample coat_sample(const CoatedConductorParams *p, pint active, pvec3 wo, pfloat uc, pfloat u0, pfloat u1,
                                 int radiance, int allow_r, int allow_t)
{
    const pint smooth = p->coat_smooth | (p->eta == 1.0f);
    const pint rough = active & pnot(smooth);
    pvec3 m = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    if (pany(rough)) {
        const pvec3 up = pv3_sel(wo, pv3_neg(wo), wo.z < 0.0f);
        m = pv3_sel(m, mf_sample_vndf(up, p->coat.ax, p->coat.ay, p->coat.beckmann, u0, u1, rough), rough);
    }
    pfloat mo = pv3_dot(wo, m);
    const pfloat F = fresnel_dielectric(mo, p->eta), T = 1.0f - F;
    const pfloat pr = allow_r ? F : PFLOAT(0.0f), pt = allow_t ? T : PFLOAT(0.0f);
    const pint refl = uc * (pr + pt) < pr;
    /* pbrt's Refract: about m turned to wo's side, into eta or, from inside, 1 / eta */
    const pint below = mo < 0.0f;
    const pfloat etap = below ? 1.0f / p->eta : p->eta;
    pvec3 wt;
    const pint tok = refract_about(wo, pv3_sel(m, pv3_neg(m), below), etap, &wt, active & pnot(refl));
    const pvec3 wi = pv3_sel(wt, reflect_about(wo, m), refl);
    pint ok = active & (pr + pt > 0.0f) & (wo.z != 0.0f);
    ok &= refl ? (wi.z * wo.z > 0.0f) : tok & (wi.z * wo.z < 0.0f);
    const pfloat chosen = (refl ? pr : pt) / (pr + pt);
    const pfloat cos_i = pabs(wi.z);
    pfloat f = (refl ? F : T) / cos_i;
    if (radiance) f = refl ? f : f / (etap * etap);
    pfloat pdf = chosen;
    if (pany(rough)) {
        const pfloat mi = pv3_dot(wi, m);
        const pfloat D = mf_d(m, p->coat.ax, p->coat.ay, p->coat.beckmann), G = mf_g(&p->coat, wo, wi, m);
        const pfloat pm = coat_vndf_pdf(p, wo, m);
        const pfloat denom = (mi + mo / etap) * (mi + mo / etap);
        pfloat ft = T * D * G * pabs(mi * mo / (wi.z * wo.z * denom));
        if (radiance) ft = ft / (etap * etap);
        f = rough ? (refl ? D * G * F / pabs(4.0f * wi.z * wo.z) : ft) : f;
        pdf = rough ? (refl ? pm / (4.0f * pabs(mo)) : pm * pabs(mi) / denom) * chosen : pdf;
    }
    ok &= (pdf > 0.0f) & (f > 0.0f) & pisfinite(pdf) & pisfinite(f);
    CoatSample s;
    s.wi = wi;
    s.f = ok ? f : PFLOAT(0.0f);
    s.pdf = ok ? pdf : PFLOAT(0.0f);
    s.ok = ok;
    s.specular = smooth;
    s.transmitted = pnot(refl);
    return s;
}

/* the weight f |cos| / pdf of a coating sample */
RT_INLINE pfloat coat_weight(const CoatSample *s)
{
    return s->ok ? s->f * pabs(s->wi.z) / s->pdf : PFLOAT(0.0f);
}

#define COAT_RADIANCE 1, 0, 1 /* radiance transport, transmission only */
#define COAT_IMPORTANCE 0, 0, 1

/* The walks' first two draws, as pbrt-v4's f and PDF make them: the coating's transmitted samples of
 * wo (radiance) and of wi (importance); the lanes where both exist */
RT_INLINE pint coat_through(const CoatedConductorParams *p, pint live, pvec3 wo, pvec3 wi, CoatRng *r, CoatSample *wos,
                            CoatSample *wis)
{
    const pfloat a0 = coat_next(r), a1 = coat_next(r), a2 = coat_next(r);
    *wos = coat_sample(p, live, wo, a0, a1, a2, COAT_RADIANCE);
    const pfloat b0 = coat_next(r), b1 = coat_next(r), b2 = coat_next(r);
    *wis = coat_sample(p, live, wi, b0, b1, b2, COAT_IMPORTANCE);
    return live & wos->ok & wis->ok;
}

/* The estimate of f(wo, wi), times cos_i (both above the surface), pbrt-v4's LayeredBxDF::f.  Not
 * inlined (nor coated_pdf, coatedconductor_sample): each walk is large, and kernels call the BSDF from
 * several places; inlined, this type alone more than doubled the build of a kernel with every type. */
__attribute__((noinline)) pvec3 coated_f(const CoatedConductorParams *p, pint active, pvec3 wo, pvec3 wi)
{
    const pint ok = active & (wo.z > 0.0f) & (wi.z > 0.0f);
    if (!pany(ok)) return pv3_zero();
    pfloat unused;
    const pfloat top = coat_f(p, ok, wo, wi, 1, 1, 1, &unused) * convert_pfloat(p->samples);
    pvec3 f = pv3(top, top, top);
    CoatRng r = coat_rng(0u, wo, wi);
    const pfloat top_z = pfmax(p->thickness, PFLOAT(1.17549435e-38f)); /* the coating's height; wi leaves there */
    for (int s = 0; pany(ok & (PINT(s) < p->samples)); ++s) {
        pint live = ok & (PINT(s) < p->samples);
        CoatSample wos, wis;
        live = coat_through(p, live, wo, wi, &r, &wos, &wis);
        const pfloat bw = coat_weight(&wos);
        pvec3 beta = pv3(bw, bw, bw), w = wos.wi;
        pfloat z = top_z;
        const pvec3 wis_up = pv3_neg(wis.wi);
        const pfloat wis_f = live ? wis.f / wis.pdf : PFLOAT(0.0f);
        const pfloat wis_scale = live ? coat_tr(p->thickness, wis.wi) * wis.f / wis.pdf : PFLOAT(0.0f);
        for (int depth = 0; pany(live & (PINT(depth) < p->max_depth)); ++depth) {
            live &= PINT(depth) < p->max_depth;
            if (depth > 3) { /* Russian roulette */
                const pfloat mb = pv3_max3(beta), q = pfmax(PFLOAT(0.0f), 1.0f - mb);
                const pint rr = live & (mb < 0.25f);
                live &= pnot(rr & (coat_next_in(&r, live) < q));
                beta = pv3_sel(beta, pv3_div(beta, rr ? 1.0f - q : PFLOAT(1.0f)), live);
            }
            pint at_layer = live; /* the lanes that reach the coating or the metal in this step */
            const pint medium = live & p->scattering;
            if (pany(medium)) { /* a scattering coating: where does the medium stop the walk? */
                const pfloat dz = coat_free_height(coat_next_in(&r, medium), w);
                const pfloat zp = w.z > 0.0f ? z + dz : z - dz;
                const pint inside = medium & (zp > 0.0f) & (zp < top_z) & (zp != z);
                at_layer &= pnot(medium & ((zp == z) | inside)); /* zp == z: pbrt steps on in place */
                z = (medium & pnot(inside)) ? pfmin(pfmax(zp, PFLOAT(0.0f)), top_z) : z;
                if (pany(inside)) {
                    /* towards wi's refracted direction (the only way out through a smooth coating) */
                    const pfloat ph = phase_hg(p->g, pv3_dot(w, wis.wi));
                    const pfloat wt = p->coat_smooth ? PFLOAT(1.0f) : coat_power(wis.pdf, ph);
                    const pfloat sw = inside ? ph * wt * coat_tr(zp - top_z, wis.wi) * wis_f : PFLOAT(0.0f);
                    f = pv3_add(f, pv3_scale(pv3_mul(beta, p->albedo), sw));
                    const pfloat u1 = coat_next_in(&r, inside), u2 = coat_next_in(&r, inside);
                    pfloat pp;
                    const pvec3 wn = phase_sample_pg(PINT(PHASE_HG), p->g, pv3_neg(w), u1, u2, &pp);
                    const pint moved = inside & (pp > 0.0f) & (wn.z != 0.0f);
                    beta = pv3_sel(beta, pv3_mul(beta, p->albedo), moved); /* p / pdf = 1 */
                    w = pv3_sel(w, wn, moved);
                    z = moved ? zp : z;
                    const pint out = moved & (wn.z > 0.0f) & pnot(p->coat_smooth);
                    if (pany(out)) { /* out through a rough coating towards wi */
                        pfloat pe;
                        const pfloat fe = coat_f(p, out, pv3_neg(w), wi, 1, 0, 1, &pe);
                        const pfloat so = out ? coat_tr(zp - top_z, w) * fe * coat_power(pp, pe) : PFLOAT(0.0f);
                        f = pv3_add(f, pv3_scale(beta, so));
                    }
                }
            }
            const pint clear = at_layer & pnot(p->scattering); /* straight across, attenuated */
            z = clear ? (z == top_z ? PFLOAT(0.0f) : top_z) : z;
            beta = pv3_sel(beta, pv3_scale(beta, coat_tr(p->thickness, w)), clear);
            const pint at_metal = at_layer & (z == 0.0f), at_coat = at_layer & (z == top_z);
            if (pany(at_metal)) {
                const pvec3 wb = pv3_neg(w);
                const pint rough_metal = at_metal & pnot(p->metal.smooth);
                if (pany(rough_metal)) { /* towards wi's refracted direction */
                    pfloat pb;
                    const pvec3 fb = conductor_eval(&p->metal, rough_metal, wb, wis_up, &pb);
                    const pfloat mis = COATED_NEE == 0 ? coat_power(wis.pdf, pb) : PFLOAT(COATED_NEE == 1);
                    const pfloat wt = p->coat_smooth ? PFLOAT(1.0f) : mis; /* the only way through a smooth one */
                    f = pv3_add(f, pv3_sel(pv3_zero(), pv3_mul(beta, pv3_scale(fb, wt * wis_scale)), rough_metal));
                }
                pvec3 wn;
                pfloat pc;
                pint dc;
                const pfloat c0 = coat_next_in(&r, at_metal), c1 = coat_next_in(&r, at_metal);
                const pvec3 g = conductor_sample(&p->metal, at_metal, wb, c0, c1, &wn, &pc, &dc);
                const pint bounced = at_metal & (dc | (pc > 0.0f)) & (pv3_max3(g) > 0.0f) & (wn.z != 0.0f);
                live &= pnot(at_metal & pnot(bounced));
                beta = pv3_sel(beta, pv3_sel(pv3_zero(), pv3_mul(beta, g), bounced), at_metal);
                w = pv3_sel(w, wn, at_metal);
                const pint rough_coat = bounced & pnot(p->coat_smooth);
                if (pany(rough_coat)) { /* out through the coating towards wi */
                    pfloat pe;
                    const pfloat fe = coat_f(p, rough_coat, pv3_neg(w), wi, 1, 0, 1, &pe);
                    const pfloat mis = COATED_NEE == 0 ? coat_power(pc, pe) : PFLOAT(COATED_NEE == 2);
                    const pfloat wt = dc ? PFLOAT(1.0f) : mis; /* the only way from a mirror */
                    const pfloat s = rough_coat ? coat_tr(p->thickness, w) * fe * wt : PFLOAT(0.0f);
                    f = pv3_add(f, pv3_scale(beta, s));
                }
            }
            if (pany(at_coat)) { /* the coating's underside reflects back down */
                const pfloat d0 = coat_next_in(&r, at_coat), d1 = coat_next_in(&r, at_coat);
                const pfloat d2 = coat_next_in(&r, at_coat);
                const CoatSample bs = coat_sample(p, at_coat, pv3_neg(w), d0, d1, d2, 1, 1, 0);
                live &= pnot(at_coat & pnot(bs.ok));
                beta = pv3_sel(beta, pv3_scale(beta, coat_weight(&bs)), at_coat);
                w = pv3_sel(w, bs.wi, at_coat);
            }
        }
    }
    return pv3_sel(pv3_zero(), pv3_scale(f, wi.z / convert_pfloat(p->samples)), ok);
}

/* The estimate of the density of coatedconductor_sample's directions that MIS takes (both above the surface),
 * pbrt-v4's LayeredBxDF::PDF */
__attribute__((noinline)) pfloat coated_pdf(const CoatedConductorParams *p, pint active, pvec3 wo, pvec3 wi)
{
    const pint ok = active & (wo.z > 0.0f) & (wi.z > 0.0f);
    if (!pany(ok)) return PFLOAT(0.0f);
    pfloat sum;
    (void)coat_f(p, ok, wo, wi, 1, 1, 0, &sum);
    sum = sum * convert_pfloat(p->samples);
    CoatRng r = coat_rng(1u, wi, wo);
    for (int s = 0; pany(ok & (PINT(s) < p->samples)); ++s) {
        pint live = ok & (PINT(s) < p->samples);
        CoatSample wos, wis;
        live = coat_through(p, live, wo, wi, &r, &wos, &wis);
        const pvec3 wos_up = pv3_neg(wos.wi), wis_up = pv3_neg(wis.wi);
        pfloat pb;
        (void)conductor_eval(&p->metal, live, wos_up, wis_up, &pb); /* 0 for a smooth conductor */
        const pint smooth_coat = live & p->coat_smooth, rough_coat = live & pnot(p->coat_smooth);
        sum += smooth_coat ? pb : PFLOAT(0.0f);
        if (pany(rough_coat)) { /* the conductor's sample of wos, out through the coating, MIS with wis */
            pvec3 wn;
            pfloat pc;
            pint dc;
            const pfloat c0 = coat_next(&r), c1 = coat_next(&r);
            const pvec3 g = conductor_sample(&p->metal, rough_coat, wos_up, c0, c1, &wn, &pc, &dc);
            const pint rok = rough_coat & (dc | (pc > 0.0f)) & (pv3_max3(g) > 0.0f);
            pfloat pt;
            (void)coat_f(p, rok, pv3_neg(wn), wi, 1, 1, 1, &pt);
            const pfloat mis = coat_power(wis.pdf, pb) * pb + coat_power(pc, pt) * pt;
            sum += rok ? (dc ? pt : mis) : PFLOAT(0.0f);
        }
    }
    const pfloat q = 0.1f * (0.25f * INV_PI_F) + 0.9f * sum / convert_pfloat(p->samples);
    return ok ? q : PFLOAT(0.0f);
}

/* A sample of pbrt-v4's LayeredBxDF::Sample_f: the weight f |cos| / pdf; *pdf the estimate MIS takes
 * (0 for a delta sample). */
__attribute__((noinline)) pvec3 coatedconductor_sample(const CoatedConductorParams *p, pint active, pvec3 wo,
                                                       pfloat u0, pfloat u1, pfloat u2, pvec3 *wi, pfloat *pdf,
                                                       pint *delta)
{
    pint ok = active & (wo.z > 0.0f);
    const CoatSample bs = coat_sample(p, ok, wo, u2, u0, u1, 1, 1, 1);
    ok &= bs.ok;
    pint done = ok & pnot(bs.transmitted), specular = bs.specular;
    const pfloat rw = coat_weight(&bs);
    pvec3 weight = pv3(rw, rw, rw), out = bs.wi;
    pint walking = ok & bs.transmitted;
    if (pany(walking)) {
        CoatRng r = coat_rng(2u, wo, pv3(u0, u1, u2));
        const pfloat f0 = bs.f * pabs(bs.wi.z);
        const pfloat top_z = pfmax(p->thickness, PFLOAT(1.17549435e-38f));
        pvec3 f = pv3(f0, f0, f0), w = bs.wi;
        pfloat q = bs.pdf, z = top_z;
        for (int depth = 0; pany(walking & (PINT(depth) < p->max_depth)); ++depth) {
            walking &= PINT(depth) < p->max_depth;
            if (depth > 3) { /* Russian roulette */
                const pfloat rr_beta = pv3_max3(f) / q, kill = pfmax(PFLOAT(0.0f), 1.0f - rr_beta);
                const pint rr = walking & (rr_beta < 0.25f);
                walking &= pnot(rr & (coat_next_in(&r, walking) < kill));
                q = rr ? q * (1.0f - kill) : q;
            }
            walking &= w.z != 0.0f;
            pint at_layer = walking;
            const pint medium = walking & p->scattering;
            if (pany(medium)) { /* a scattering coating */
                const pfloat dz = coat_free_height(coat_next_in(&r, medium), w);
                const pfloat zp = w.z > 0.0f ? z + dz : z - dz;
                walking &= pnot(medium & (zp == z)); /* as pbrt: no sample */
                const pint inside = walking & medium & (zp > 0.0f) & (zp < top_z);
                at_layer = walking & pnot(inside);
                z = (walking & medium & pnot(inside)) ? pfmin(pfmax(zp, PFLOAT(0.0f)), top_z) : z;
                if (pany(inside)) {
                    const pfloat v1 = coat_next_in(&r, inside), v2 = coat_next_in(&r, inside);
                    pfloat pp;
                    const pvec3 wn = phase_sample_pg(PINT(PHASE_HG), p->g, pv3_neg(w), v1, v2, &pp);
                    const pint moved = inside & (pp > 0.0f) & (wn.z != 0.0f);
                    walking &= pnot(inside & pnot(moved));
                    f = pv3_sel(f, pv3_scale(pv3_mul(f, p->albedo), pp), moved);
                    q = moved ? q * pp : q;
                    specular &= pnot(moved);
                    w = pv3_sel(w, wn, moved);
                    z = moved ? zp : z;
                }
            }
            const pint clear = at_layer & pnot(p->scattering);
            z = clear ? (z == top_z ? PFLOAT(0.0f) : top_z) : z;
            f = pv3_sel(f, pv3_scale(f, coat_tr(p->thickness, w)), clear);
            const pint at_metal = at_layer & (z == 0.0f), at_coat = at_layer & (z == top_z);
            if (pany(at_metal)) {
                pvec3 wn;
                pfloat pc;
                pint dc;
                const pfloat c0 = coat_next_in(&r, at_metal), c1 = coat_next_in(&r, at_metal);
                const pvec3 g = conductor_sample(&p->metal, at_metal, pv3_neg(w), c0, c1, &wn, &pc, &dc);
                walking &= pnot(at_metal & pnot((dc | (pc > 0.0f)) & (pv3_max3(g) > 0.0f)));
                /* f_c |cos| = g pc (a mirror: g) */
                f = pv3_sel(f, pv3_scale(pv3_mul(f, g), dc ? PFLOAT(1.0f) : pc), at_metal);
                q = at_metal & pnot(dc) ? q * pc : q;
                specular &= dc | pnot(at_metal) | pnot(walking);
                w = pv3_sel(w, wn, at_metal);
            }
            if (pany(at_coat)) { /* the coating from below: out, or back down */
                const pfloat d0 = coat_next_in(&r, at_coat), d1 = coat_next_in(&r, at_coat);
                const pfloat d2 = coat_next_in(&r, at_coat);
                const CoatSample cs = coat_sample(p, at_coat, pv3_neg(w), d0, d1, d2, 1, 1, 1);
                walking &= pnot(at_coat & pnot(cs.ok));
                const pint here = at_coat & walking;
                specular &= cs.specular | pnot(here);
                const pint leave = here & cs.transmitted;
                const pvec3 fl = pv3_scale(f, cs.f * pabs(cs.wi.z) / (q * cs.pdf));
                weight = pv3_sel(weight, fl, leave);
                out = pv3_sel(out, cs.wi, leave);
                done |= leave;
                walking &= pnot(leave);
                f = pv3_sel(f, pv3_scale(f, cs.f * pabs(cs.wi.z)), here);
                q = here ? q * cs.pdf : q;
                w = pv3_sel(w, cs.wi, here);
            }
        }
    }
    *wi = out;
    *delta = done & specular;
    const pint mis = done & pnot(specular);
    *pdf = pany(mis) ? (mis ? coated_pdf(p, mis, wo, out) : PFLOAT(0.0f)) : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), weight, done);
}

#define COATED_CONDUCTOR_ALPHA_U 0 /* Material.table entries */
#define COATED_CONDUCTOR_ALPHA_V 1
#define COATED_THICKNESS 2
#define COATED_MAX_DEPTH 3
#define COATED_SAMPLES 4
#define COATED_ALBEDO 5 /* 5, 6, 7: r, g, b */
#define COATED_G 8

/* The parameters from the lanes' Material fields and table. */
RT_INLINE CoatedConductorParams coatedconductor_params(const MaterialLanes *m)
{
    CoatedConductorParams p;
    p.coat = microfacet_params(m, &p.coat_smooth);
    p.eta = m->ior;
    const pint t = m->rec + FIELD_INDEX(Material, table);
    const pfloat cu = pgather(m->records, t + COATED_CONDUCTOR_ALPHA_U);
    const pfloat cv = pgather(m->records, t + COATED_CONDUCTOR_ALPHA_V);
    p.metal.f0 = pv3_zero();
    p.metal.eta = m->eta;
    p.metal.k = m->k;
    p.metal.schlick = PINT(0);
    p.metal.smooth = microfacet_is_smooth(cu) & microfacet_is_smooth(cv);
    p.metal.d.ax = pfmax(cu, PFLOAT(1e-4f));
    p.metal.d.ay = pfmax(cv, PFLOAT(1e-4f));
    p.metal.d.beckmann = p.metal.d.separable = PINT(0);
    p.thickness = pgather(m->records, t + COATED_THICKNESS);
    const pint depth = convert_pint(pgather(m->records, t + COATED_MAX_DEPTH));
    const pint samples = convert_pint(pgather(m->records, t + COATED_SAMPLES));
    p.max_depth = depth < 1 ? PINT(1) : depth; /* the loaders give at least 1 */
    p.samples = samples < 1 ? PINT(1) : samples;
    p.albedo = pv3(pgather(m->records, t + COATED_ALBEDO), pgather(m->records, t + COATED_ALBEDO + 1),
                   pgather(m->records, t + COATED_ALBEDO + 2));
    p.g = pgather(m->records, t + COATED_G);
    p.scattering = pv3_max3(p.albedo) > 0.0f;
    return p;
}

RT_INLINE pvec3 coatedconductor_eval(const CoatedConductorParams *p, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    *pdf = coated_pdf(p, active, wo, wi);
    return coated_f(p, active, wo, wi);
}

/* mask: a rough coating, a rough conductor or a scattering coating (else every sample is a delta sample) */
RT_INLINE pint coatedconductor_nondelta(const MaterialLanes *m)
{
    const CoatedConductorParams p = coatedconductor_params(m);
    return pnot(p.coat_smooth & p.metal.smooth) | p.scattering;
}

/* the albedo guide: the coating's Fresnel reflectance at the viewing angle, and the conductor's for the rest */
RT_INLINE pvec3 coatedconductor_albedo(const MaterialLanes *m, pfloat cos_o)
{
    const CoatedConductorParams p = coatedconductor_params(m);
    const pfloat F = fresnel_dielectric(cos_o, p.eta);
    return pv3_add(pv3(F, F, F), pv3_scale(conductor_fresnel(&p.metal, cos_o), 1.0f - F));
}

#define MATERIAL_CASE_COATEDCONDUCTOR(X) \
    X(COATEDCONDUCTOR, coatedconductor, CoatedConductorParams, coatedconductor_params(m), \
      coatedconductor_eval(&P, K, lo, li, &q), coatedconductor_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d), \
      coatedconductor_nondelta(m), coatedconductor_albedo(m, cos_o))

#endif
