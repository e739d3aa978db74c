//! Joining subpaths and weighing every strategy (s, t) by the power heuristic over all
//! strategies that could have made the same path (and vertex merging, for VCM).

use glam::{Vec2, Vec3A};

use super::density::{Joined, nee_over_start};
use super::subpath::Ctx;
use super::vertex::{Kind, Vertex};
use crate::bsdf::TransportMode;
use crate::integrator::RayStats;
use crate::light::ShadowTarget;
use crate::sampler::Sampler;
use crate::spectrum::{Spectrum, is_black};

/// The first vertex of a path that merging may make, counted from the light (z_0 on the
/// emitter). A merge at z_1 is direct illumination estimated from the light subpaths' first
/// hits; the power heuristic counts the η light subpaths of an iteration as η independent
/// samples and so gives those merges much of the weight of light sampling, which has far
/// less variance there (every pixel's merges share the same few nearby light vertices).
/// Leaving z_1 to the connections — every path that merging at z_1 makes, light sampling
/// (s = 1) makes too — lowers VCM's error on every scene measured (docs/src/benchmarks/speed-vs-error.md).
pub(in crate::integrator) const FIRST_MERGE: usize = 2;

impl Ctx<'_> {
    /// The power-heuristic weight of the strategy (s, t), with the connection's endpoints
    /// replaced by `sampled` where it made them (s = 1: a light point; t = 1: the lens), and
    /// vertex merging among the strategies when `merge` > 0 (see [`Self::mis_sums`]).
    #[allow(clippy::too_many_arguments)]
    pub(in crate::integrator) fn mis_weight(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        sampled: Option<&Vertex>,
        s: usize,
        t: usize,
        merge: f32,
        joined: Option<&Joined>,
    ) -> f32 {
        if s + t == 2 {
            return 1.0;
        }
        1.0 / (1.0 + self.mis_sums(light, camera, sampled, s, t, merge, joined))
    }

    /// Σ over the other strategies j of the path made by (s, t) of (p_j / p_{s,t})²: the
    /// connections, and with `merge` = η π r² > 0 (light paths per iteration × the merging
    /// disc) also vertex merging at each non-specular vertex from the light's second on
    /// ([`FIRST_MERGE`]; Georgiev et al. 2012; p_merge at z = p of the connection that samples
    /// z from one side × the density of z from the other × η π r²). (A merge's own weight is
    /// VCM's, from sums kept along the subpaths.)
    #[allow(clippy::too_many_arguments)]
    fn mis_sums(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        sampled: Option<&Vertex>,
        s: usize,
        t: usize,
        merge: f32,
        joined: Option<&Joined>,
    ) -> f32 {
        // The four vertices whose reverse densities the connection changes, and the two
        // endpoints, which a connection never treats as specular.
        let qs = match (s, sampled) {
            (0, _) => None,
            (1, Some(v)) => Some(v),
            _ => Some(&light[s - 1]),
        };
        let pt = match (t, sampled) {
            (1, Some(v)) => v,
            _ => &camera[t - 1],
        };
        let qs_minus = (s >= 2).then(|| &light[s - 2]);
        let pt_minus = (t >= 2).then(|| &camera[t - 2]);
        // s = 0: pt is an emitter the camera path hit; as a light subpath would have made it.
        let emitted = match (qs, pt_minus) {
            (None, Some(m)) => self.pdf_le(pt, m),
            _ => (0.0, 0.0),
        };
        let (pt_rev, pt_minus_rev, qs_rev, qs_minus_rev) = match joined {
            Some(j) => (
                j.pt_rev,
                Some(j.pt_minus_rev),
                Some(j.qs_rev),
                Some(j.qs_minus_rev),
            ),
            None => (
                match qs {
                    Some(q) => self.pdf(q, qs_minus, pt),
                    None => emitted.0,
                },
                pt_minus.map(|m| match qs {
                    Some(q) => self.pdf(pt, Some(q), m),
                    None => emitted.1,
                }),
                qs.map(|q| self.pdf(pt, pt_minus, q)),
                match (qs, qs_minus) {
                    (Some(q), Some(m)) => Some(self.pdf(q, Some(pt), m)),
                    _ => None,
                },
            ),
        };
        let remap = |p: f32| if p != 0.0 { p * p } else { 1.0 };
        // Merging at a vertex whose density from the other side is `rev` (ratio `before`
        // while the vertex is still its own side's) or from its own side `fwd` (`after`).
        let merged = |before: f32, after: f32, rev: f32, fwd: f32| {
            if rev != 0.0 {
                before * remap(rev * merge)
            } else if fwd != 0.0 {
                after * remap(fwd * merge)
            } else {
                after
            }
        };
        let mut sum = 0.0f32;

        // Camera side: strategies with fewer camera vertices.
        let cam = |i: usize| -> (f32, f32, bool) {
            let v = if i == t - 1 { pt } else { &camera[i] };
            let rev = if i == t - 1 {
                pt_rev
            } else if i + 2 == t {
                pt_minus_rev.unwrap_or(v.pdf_rev)
            } else {
                v.pdf_rev
            };
            let delta = if i == t - 1 { false } else { v.delta };
            (rev, v.pdf_fwd, delta)
        };
        // Strategy s = 1 samples the light point by light sampling, not as a light subpath
        // starts ([`Self::nee_ratio`]): its term, and with s = 1 the own density, take k².
        let k2 = |v: &Vertex| v.nee * v.nee;
        // (s = 0: the emitter the camera path hit; its s = 1 term is the first below.)
        let hit_k2 = match (s, pt_minus) {
            (0, Some(m)) => self.nee_ratio(pt, m, emitted.0).powi(2),
            _ => 1.0,
        };
        let mut ri = 1.0f32;
        for i in (1..t).rev() {
            let (rev, fwd, delta) = cam(i);
            let before = ri;
            ri *= remap(rev) / remap(fwd);
            if !delta && !cam(i - 1).2 {
                sum += if i == t - 1 { ri * hit_k2 } else { ri };
            }
            // Merges from the light's second vertex on (never at the emitter a camera path
            // hit, nor where the light subpath's first hit would be).
            if merge > 0.0 && !delta && s + t - 1 - i >= FIRST_MERGE {
                sum += merged(before, ri, rev, fwd);
            }
        }

        // Light side: strategies with fewer light vertices.
        let lig = |i: usize| -> (f32, f32, bool) {
            let v = match (&qs, i + 1 == s) {
                (Some(q), true) => q,
                _ => &light[i],
            };
            let rev = if i + 1 == s {
                qs_rev.unwrap_or(v.pdf_rev)
            } else if i + 2 == s {
                qs_minus_rev.unwrap_or(v.pdf_rev)
            } else {
                v.pdf_rev
            };
            let delta = if i + 1 == s { false } else { v.delta };
            (rev, v.pdf_fwd, delta)
        };
        let mut ri = 1.0f32;
        for i in (0..s).rev() {
            let (rev, fwd, delta) = lig(i);
            let before = ri;
            ri *= remap(rev) / remap(fwd);
            if merge > 0.0 && i >= FIRST_MERGE && !delta {
                sum += merged(before, ri, rev, fwd);
            }
            let delta_light = if i > 0 {
                lig(i - 1).2
            } else {
                let first = match (&qs, s) {
                    (Some(q), 1) => q,
                    _ => &light[0],
                };
                self.is_delta_light(first)
            };
            if !delta && !delta_light {
                sum += if i == 1 { ri * k2(&light[0]) } else { ri };
            }
        }
        match (s, qs) {
            (1, Some(v)) => sum / k2(v),
            _ => sum,
        }
    }

    /// The contribution of strategy (s, t), MIS-weighted; for t = 1 also where it lands.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::integrator) fn connect(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        s: usize,
        t: usize,
        merge: f32,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
    ) -> (Spectrum, Option<Vec2>) {
        let (l, w, raster) = self.connect_unweighted(light, camera, s, t, merge, sampler, stats);
        (l * w, raster)
    }

    /// [`Self::connect`] with the contribution and its MIS weight apart.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::integrator) fn connect_unweighted(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        s: usize,
        t: usize,
        merge: f32,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
    ) -> (Spectrum, f32, Option<Vec2>) {
        let pt = &camera[t - 1];
        let mut raster = None;
        let mut sampled = None;
        let mut joined = None;
        let l = if s == 0 {
            // The camera subpath hit an emitter.
            if t < 2 || self.light_of(pt).is_none() {
                return (Spectrum::ZERO, 0.0, None);
            }
            pt.beta * self.le(pt, &camera[t - 2])
        } else if t == 1 {
            // Light tracing: the light subpath's vertex seen through the lens.
            let qs = &light[s - 1];
            if !self.connectible(qs) {
                return (Spectrum::ZERO, 0.0, None);
            }
            let u = sampler.get_2d();
            let Some(is) = self.camera.sample_wi(qs.p, u) else {
                return (Spectrum::ZERO, 0.0, None);
            };
            if is.pdf <= 0.0 || is.we <= 0.0 {
                return (Spectrum::ZERO, 0.0, None);
            }
            let cam = Vertex::point(
                Kind::Camera,
                is.p_lens,
                Vec3A::ZERO,
                Vec3A::ZERO,
                Spectrum::splat(is.we / is.pdf),
                0.0,
            );
            let (f, to_cam, to_q_minus) = self.f_and_pdfs(qs, &cam, TransportMode::Importance);
            let mut l = qs.beta * f * cam.beta;
            if qs.on_surface() {
                l *= is.wi.dot(qs.ns).abs();
            }
            // (s = 1: f is zero at the light point, no weight needed.)
            if s >= 2 {
                joined = Some(Joined {
                    pt_rev: qs.convert_density(to_cam, &cam),
                    pt_minus_rev: 0.0,
                    qs_rev: self.pdf(&cam, None, qs),
                    qs_minus_rev: qs.convert_density(to_q_minus, &light[s - 2]),
                });
            }
            if is_black(l) {
                return (Spectrum::ZERO, 0.0, None);
            }
            stats.rays += 1;
            if !self.scene.unoccluded_between(qs.end(), cam.end()) {
                return (Spectrum::ZERO, 0.0, None);
            }
            raster = Some(is.raster);
            sampled = Some(cam);
            l
        } else if s == 1 {
            // Next-event estimation: a fresh point on a light for the camera path's end.
            if !self.connectible(pt) {
                return (Spectrum::ZERO, 0.0, None);
            }
            let u = sampler.get_3d();
            let Some((li, pmf)) = self.scene.lights.choose(u.x) else {
                return (Spectrum::ZERO, 0.0, None);
            };
            let light = self.scene.lights.get(li);
            let Some(ls) = light.sample_li(pt.p, Vec2::new(u.y, u.z)) else {
                return (Spectrum::ZERO, 0.0, None);
            };
            if ls.pdf <= 0.0 {
                return (Spectrum::ZERO, 0.0, None);
            }
            let beta = ls.li / (ls.pdf * pmf);
            let mut v = match ls.target {
                ShadowTarget::Point { p, p_error, n } => {
                    Vertex::point(Kind::Light(li), p, p_error, n, beta, 0.0)
                }
                ShadowTarget::Infinite => Vertex::at_infinity(li, pt.p, ls.wi, beta),
            };
            // Densities of v as a light subpath's start and of pt as its next vertex.
            let (start, emit_to_pt) = self.pdf_le(&v, pt);
            v.pdf_fwd = start;
            // [`Self::nee_ratio`] from the densities at hand (both with the light's choice).
            v.nee = if v.infinite {
                1.0
            } else {
                nee_over_start(pt.convert_density(ls.pdf * pmf, &v), v.pdf_fwd)
            };
            let (f, to_v, to_p_minus) = self.f_and_pdfs(pt, &v, TransportMode::Radiance);
            let mut l = pt.beta * f * v.beta;
            if pt.on_surface() {
                l *= ls.wi.dot(pt.ns).abs();
            }
            joined = Some(Joined {
                pt_rev: emit_to_pt,
                pt_minus_rev: pt.convert_density(to_p_minus, &camera[t - 2]),
                qs_rev: pt.convert_density(to_v, &v),
                qs_minus_rev: 0.0,
            });
            if is_black(l) {
                return (Spectrum::ZERO, 0.0, None);
            }
            stats.rays += 1;
            // Toward a light at infinity by direction (`pt` is a surface: t ≥ 2 here).
            let visible = if v.infinite {
                pt.si.is_some_and(|si| self.scene.unoccluded(&si, &ls))
            } else {
                self.scene.unoccluded_between(pt.end(), v.end())
            };
            if !visible {
                return (Spectrum::ZERO, 0.0, None);
            }
            sampled = Some(v);
            l
        } else {
            // Both subpaths joined by a shadow ray; the densities the join changes come with
            // the two f's.
            let qs = &light[s - 1];
            if !self.connectible(qs) || !self.connectible(pt) {
                return (Spectrum::ZERO, 0.0, None);
            }
            let (f_q, to_pt, to_q_minus) = self.f_and_pdfs(qs, pt, TransportMode::Importance);
            let (f_p, to_q, to_p_minus) = self.f_and_pdfs(pt, qs, TransportMode::Radiance);
            let l = qs.beta * f_q * f_p * pt.beta;
            if is_black(l) {
                return (Spectrum::ZERO, 0.0, None);
            }
            joined = Some(Joined {
                pt_rev: qs.convert_density(to_pt, pt),
                pt_minus_rev: pt.convert_density(to_p_minus, &camera[t - 2]),
                qs_rev: pt.convert_density(to_q, qs),
                qs_minus_rev: qs.convert_density(to_q_minus, &light[s - 2]),
            });
            let w = pt.p - qs.p;
            let d2 = w.length_squared();
            if d2 == 0.0 {
                return (Spectrum::ZERO, 0.0, None);
            }
            let wn = w / d2.sqrt();
            let g = qs.ns.dot(wn).abs() * pt.ns.dot(wn).abs() / d2;
            stats.rays += 1;
            if !self.scene.unoccluded_between(qs.end(), pt.end()) {
                return (Spectrum::ZERO, 0.0, None);
            }
            l * g
        };
        if is_black(l) {
            return (Spectrum::ZERO, 0.0, None);
        }
        let w = self.mis_weight(
            light,
            camera,
            sampled.as_ref(),
            s,
            t,
            merge,
            joined.as_ref(),
        );
        (l, w, raster)
    }
}
