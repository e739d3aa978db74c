//! Path-space vertices of BDPT's subpaths: where they are, what they carry, and the
//! densities of sampling them in area measure.

use glam::Vec3A;

use crate::bsdf::TransportMode;
use crate::scene::SurfaceInteraction;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(in crate::integrator) enum Kind {
    Camera,
    /// A point on a light (the first vertex of a light subpath, or one sampled for s = 1).
    Light(u32),
    Surface,
}

/// A subpath vertex.
#[derive(Debug, Clone, Copy)]
pub(in crate::integrator) struct Vertex {
    pub(in crate::integrator) kind: Kind,
    pub(in crate::integrator) p: Vec3A,
    pub(in crate::integrator) p_error: Vec3A,
    /// Geometric normal; zero for a point in space (a pinhole, a point light).
    pub(in crate::integrator) ng: Vec3A,
    /// Shading normal (the geometric one where there is no surface to shade).
    pub(in crate::integrator) ns: Vec3A,
    /// For surfaces: the hit, and the direction toward the previous vertex of the subpath.
    /// For a light at infinity: the unit direction toward it.
    pub(in crate::integrator) si: Option<SurfaceInteraction>,
    pub(in crate::integrator) wo: Vec3A,
    pub(in crate::integrator) beta: Spectrum,
    /// Sampled by a specular lobe: no other strategy can make it.
    pub(in crate::integrator) delta: bool,
    /// Density of this vertex sampled from the previous one of its subpath, per unit area.
    pub(in crate::integrator) pdf_fwd: f32,
    /// Density of this vertex sampled from the next one (the other direction), per unit area.
    pub(in crate::integrator) pdf_rev: f32,
    /// A light at infinity (environment, directional): `p` stands one unit from its
    /// neighbour along the direction to the light, so directions to it are exact; its own
    /// densities are per unit solid angle, and the neighbour's from it per unit area of the
    /// disk it emits from, projected.
    pub(in crate::integrator) infinite: bool,
    /// On a light subpath's emitter vertex: [`Ctx::nee_ratio`] toward the path's next vertex
    /// (1 elsewhere): how much likelier light sampling (s = 1) makes this point than the
    /// light subpath's start did.
    pub(in crate::integrator) nee: f32,
}

impl Vertex {
    pub(in crate::integrator) fn point(
        kind: Kind,
        p: Vec3A,
        p_error: Vec3A,
        n: Vec3A,
        beta: Spectrum,
        pdf: f32,
    ) -> Self {
        Vertex {
            kind,
            p,
            p_error,
            ng: n,
            ns: n,
            si: None,
            wo: Vec3A::ZERO,
            beta,
            delta: false,
            pdf_fwd: pdf,
            pdf_rev: 0.0,
            infinite: false,
            nee: 1.0,
        }
    }

    /// A light at infinity seen from `from` in direction `wi`.
    pub(in crate::integrator) fn at_infinity(
        light: u32,
        from: Vec3A,
        wi: Vec3A,
        beta: Spectrum,
    ) -> Self {
        let mut v = Vertex::point(
            Kind::Light(light),
            from + wi,
            Vec3A::ZERO,
            Vec3A::ZERO,
            beta,
            0.0,
        );
        v.infinite = true;
        v.wo = wi;
        v
    }

    /// The vertex of a ray's hit, arrived at from direction `wo`.
    pub(in crate::integrator) fn surface(si: SurfaceInteraction, wo: Vec3A) -> Self {
        let mut v = Vertex::point(Kind::Surface, si.p, si.p_error, si.ng, Spectrum::ONE, 0.0);
        v.ns = si.ns;
        v.si = Some(si);
        v.wo = wo;
        v
    }

    pub(in crate::integrator) fn on_surface(&self) -> bool {
        self.ng != Vec3A::ZERO
    }

    pub(in crate::integrator) fn end(&self) -> (Vec3A, Vec3A, Vec3A) {
        (self.p, self.p_error, self.ng)
    }

    /// A per-solid-angle density `pdf` of sampling `next` from here, per unit area at `next`.
    /// Toward a light at infinity the density stays per solid angle; from one, `pdf` is per
    /// unit area of its disk, projected onto `next`.
    pub(in crate::integrator) fn convert_density(&self, pdf: f32, next: &Vertex) -> f32 {
        if next.infinite {
            return pdf;
        }
        if self.infinite {
            let w = (next.p - self.p).normalize_or_zero();
            return if next.on_surface() {
                pdf * next.ng.dot(w).abs()
            } else {
                pdf
            };
        }
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 {
            return 0.0;
        }
        let mut pdf = pdf / d2;
        if next.on_surface() {
            pdf *= next.ng.dot(w).abs() / d2.sqrt();
        }
        pdf
    }
}

/// Veach's correction for shading normals in importance transport (thesis §5.3, eq. 5.19):
/// |ωo·ns| |ωi·ng| / (|ωo·ng| |ωi·ns|); 1 for radiance.
pub(in crate::integrator) fn shading_correction(
    si: &SurfaceInteraction,
    wo: Vec3A,
    wi: Vec3A,
    mode: TransportMode,
) -> f32 {
    if mode == TransportMode::Radiance {
        return 1.0;
    }
    let den = wo.dot(si.ng).abs() * wi.dot(si.ns).abs();
    if den == 0.0 {
        return 0.0;
    }
    wo.dot(si.ns).abs() * wi.dot(si.ng).abs() / den
}
