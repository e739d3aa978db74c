//! Densities and throughputs of path vertices as MIS needs them: BSDF values and their
//! densities in both directions from one frame, specular lobes seen from both ends, emitters'
//! densities of starting a light subpath and of being sampled by light sampling.

use glam::{Vec2, Vec3A};

use super::subpath::Ctx;
use super::vertex::{Kind, Vertex, shading_correction};
use crate::bsdf::TransportMode;
use crate::integrator::consistent;
use crate::light::Light;
use crate::scene::SurfaceInteraction;
use crate::spectrum::{Spectrum, is_black};

impl Ctx<'_> {
    /// f at a surface vertex for light leaving toward `wo` (the vertex's own) and arriving
    /// from `next`, with the shading-normal correction of importance transport (Veach §5.3);
    /// and the densities (solid angle, as [`Self::pdf`] takes them) of sampling the direction
    /// to `next` from `wo` and of sampling `wo` from the direction to `next`, from one frame.
    /// (Where f is not zero both directions lie on one side of the shading normal, so the
    /// frame is the one `pdf` would turn to either.)
    pub(in crate::integrator) fn f_and_pdfs(
        &self,
        v: &Vertex,
        next: &Vertex,
        mode: TransportMode,
    ) -> (Spectrum, f32, f32) {
        let Some(si) = &v.si else {
            return (Spectrum::ZERO, 0.0, 0.0);
        };
        let wi = (next.p - v.p).normalize_or_zero();
        let material = self.scene.material(si.material);
        let frame = material.frame(si, v.wo);
        let (wo_l, wi_l) = (frame.to_local(v.wo), frame.to_local(wi));
        if !consistent(si, v.wo, wi, wo_l, wi_l) {
            return (Spectrum::ZERO, 0.0, 0.0);
        }
        let bsdf = material.bsdf_at(si);
        let f = bsdf.eval(wo_l, wi_l, mode) * shading_correction(si, v.wo, wi, mode);
        if is_black(f) {
            return (f, 0.0, 0.0);
        }
        (
            f,
            bsdf.pdf(wo_l, wi_l, TransportMode::Radiance),
            bsdf.pdf(wi_l, wo_l, TransportMode::Radiance),
        )
    }

    /// Density per unit area at `next` of sampling it from `v` (whose subpath came from
    /// `prev`): BSDF sampling at surfaces, emission at lights, importance at the camera.
    pub(in crate::integrator) fn pdf(
        &self,
        v: &Vertex,
        prev: Option<&Vertex>,
        next: &Vertex,
    ) -> f32 {
        let wn = (next.p - v.p).normalize_or_zero();
        let pdf = match v.kind {
            Kind::Light(_) => return self.pdf_le(v, next).1,
            Kind::Camera => self.camera.pdf_we(v.p, wn).1,
            Kind::Surface => {
                let (Some(si), Some(prev)) = (&v.si, prev) else {
                    return 0.0;
                };
                let wp = (prev.p - v.p).normalize_or_zero();
                let material = self.scene.material(si.material);
                let frame = material.frame(si, wp);
                material.bsdf_at(si).pdf(
                    frame.to_local(wp),
                    frame.to_local(wn),
                    TransportMode::Radiance,
                )
            }
        };
        v.convert_density(pdf, next)
    }

    /// The specular lobe at `si` between `wn` (toward the eye side) and `wp` (toward the
    /// light side), seen from both ends. One delta convention serves every strategy's
    /// density (BDPT's and VCM's weights, MLT's C_s = f / p_s): a specular vertex sampled from
    /// the eye side has its radiance lobe's probability; from the light side, its importance
    /// lobe's probability times c_rad |ω_n·n_g| / (c_imp |ω_p·n_g|), c the lobe's coefficient
    /// f|cos θ_i| in each mode — the Jacobian between the two directions' delta measures
    /// (η² across a refraction, shading normals). With it the ratios of densities along a
    /// specular chain are the true ones, which merging needs (a caustic seen through glass
    /// is merged or hit, never connected). `None` where no specular lobe turns one into the
    /// other.
    pub(in crate::integrator) fn delta_lobe(
        &self,
        si: &SurfaceInteraction,
        wn: Vec3A,
        wp: Vec3A,
    ) -> Option<DeltaLobe> {
        let (w_rad, p_rad) = self.lobe_between(si, wn, wp, TransportMode::Radiance)?;
        let (w_imp, p_imp) = self.lobe_between(si, wp, wn, TransportMode::Importance)?;
        let (c_rad, c_imp) = (w_rad * p_rad, w_imp * p_imp);
        let (m_rad, m_imp) = (c_rad.max_element(), c_imp.max_element());
        let cos_p = wp.dot(si.ng).abs();
        if m_rad <= 0.0 || m_imp <= 0.0 || cos_p == 0.0 {
            return None;
        }
        Some(DeltaLobe {
            c_rad,
            p_rad,
            p_imp,
            pdf_imp: p_imp * m_rad * wn.dot(si.ng).abs() / (m_imp * cos_p),
        })
    }

    /// The specular lobe at `si` that turns `wo` into `wi` in `mode`: its sampling weight
    /// (with the shading correction of importance transport) and probability.
    pub(super) fn lobe_between(
        &self,
        si: &SurfaceInteraction,
        wo: Vec3A,
        wi: Vec3A,
        mode: TransportMode,
    ) -> Option<(Spectrum, f32)> {
        let material = self.scene.material(si.material);
        let fr = material.frame(si, wo);
        let wo_l = fr.to_local(wo);
        for u in [0.0, 0.5, 0.999_999] {
            let Some(bs) = material.bsdf_at(si).sample(wo_l, u, Vec2::splat(0.5), mode) else {
                continue;
            };
            if !bs.specular || fr.to_world(bs.wi).dot(wi) < 1.0 - 1e-4 {
                continue;
            }
            if !consistent(si, wo, wi, wo_l, bs.wi) {
                return None;
            }
            return Some((bs.weight() * shading_correction(si, wo, wi, mode), bs.pdf));
        }
        None
    }

    /// Densities of the light at `v` emitting from `v` toward `to`: of choosing the light
    /// and the point `v` on it (per unit area), and of the direction, per unit area at `to`.
    /// For a light at infinity: of choosing it and the direction (per solid angle; an
    /// environment as every environment light together, as a path escaping sees them), and
    /// of the point on its disk, per unit area at `to`.
    pub(in crate::integrator) fn pdf_le(&self, v: &Vertex, to: &Vertex) -> (f32, f32) {
        let Some((i, light)) = self.light_of(v) else {
            return (0.0, 0.0);
        };
        let w = (to.p - v.p).normalize_or_zero();
        if v.infinite {
            let (disk, _) = light.pdf_le(w, w, self.bounds);
            let origin = match light {
                Light::Environment(_) => self
                    .scene
                    .lights
                    .environment()
                    .map(|(j, l)| self.scene.lights.pmf(j) * l.pdf_li_direction(-w))
                    .sum(),
                // A delta in direction.
                _ => 0.0,
            };
            return (origin, v.convert_density(disk, to));
        }
        let (pdf_pos, pdf_dir) = light.pdf_le(v.ng, w, self.bounds);
        (
            self.scene.lights.pmf(i) * pdf_pos,
            v.convert_density(pdf_dir, to),
        )
    }

    /// How much likelier light sampling (strategy s = 1) makes emitter vertex `v` from `from`
    /// than a light subpath starting there, whose density of `v` per unit area (with the
    /// light's choice) is `start` — a light subpath's `pdf_fwd`, `pdf_le`'s first. A sphere is sampled by the cone
    /// it subtends (from 30 radii away the ratio is ≈ 4 cos θ at the light); a triangle by
    /// area (1); delta lights and lights at infinity start light subpaths as light sampling
    /// picks them (1). MIS weighs s = 1 by this density, as SmallVCM does; pbrt's BDPT takes
    /// the subpath's start for it, which undervalues a sphere's light sampling against light
    /// tracing and merging.
    pub(in crate::integrator) fn nee_ratio(&self, v: &Vertex, from: &Vertex, start: f32) -> f32 {
        if v.infinite {
            return 1.0;
        }
        let Some((i, light)) = self.light_of(v) else {
            return 1.0;
        };
        let nee = from.convert_density(light.pdf_li_surface(from.p, v.p, v.ng), v);
        nee_over_start(nee * self.scene.lights.pmf(i), start)
    }

    /// Radiance an emitter vertex sends toward `to` (from a light at infinity: every
    /// environment light's along that direction).
    pub(in crate::integrator) fn le(&self, v: &Vertex, to: &Vertex) -> Spectrum {
        let Some((_, light)) = self.light_of(v) else {
            return Spectrum::ZERO;
        };
        let w = (to.p - v.p).normalize_or_zero();
        if v.infinite {
            return self
                .scene
                .lights
                .environment()
                .map(|(_, l)| l.le_direction(-w))
                .sum();
        }
        light.le_surface(v.ng, w, v.p)
    }

    /// Whether a light vertex is a delta in position (a point light) or direction (a
    /// directional light): no path can hit it.
    pub(in crate::integrator) fn is_delta_light(&self, v: &Vertex) -> bool {
        matches!(
            self.light_of(v),
            Some((_, Light::Point(_) | Light::Spot(_) | Light::Directional(_)))
        )
    }
}

/// [`Ctx::nee_ratio`] from light sampling's and a light subpath start's densities of one
/// emitter point (per unit area); 1 where either is not a density (a delta light's point).
pub(super) fn nee_over_start(nee: f32, start: f32) -> f32 {
    let k = nee / start;
    if k > 0.0 && k.is_finite() { k } else { 1.0 }
}

/// The densities per unit area that joining light vertex q_s to camera vertex p_t gives their
/// neighbours (each sampled from the other side): p_t and q_s sampled across the join, p_{t−1}
/// from p_t and q_{s−1} from q_s — from the f's frames, not evaluated again. (Light sampling
/// has no q_{s−1}, light tracing no p_{t−1}: 0 there, never read.)
pub(in crate::integrator) struct Joined {
    pub(super) pt_rev: f32,
    pub(super) pt_minus_rev: f32,
    pub(super) qs_rev: f32,
    pub(super) qs_minus_rev: f32,
}

/// A specular vertex's lobe seen from both ends ([`Ctx::delta_lobe`]).
pub(in crate::integrator) struct DeltaLobe {
    /// The radiance lobe's coefficient f |cos θ| toward the light side.
    pub(in crate::integrator) c_rad: Spectrum,
    /// Lobe probabilities sampled from the eye side (radiance) and the light side.
    pub(in crate::integrator) p_rad: f32,
    pub(in crate::integrator) p_imp: f32,
    /// The density, in the eye side's delta measure, of the light side's choice.
    pub(in crate::integrator) pdf_imp: f32,
}
