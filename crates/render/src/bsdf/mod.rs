//! Bidirectional scattering distribution functions, one per file, behind one trait.
//!
//! Conventions (pbrt-v4 / Mitsuba): directions are unit vectors in the local shading frame
//! with the normal along +z, both pointing away from the surface; `wo` is toward the viewer
//! (where light leaves), `wi` toward where light arrives from. `eval` returns f(wo, wi) in
//! sr⁻¹ without the cosine. Reflection-only BSDFs are defined for wo.z > 0; the material
//! flips the frame for the back face (two-sided). Delta (specular) lobes have `eval` and
//! `pdf` zero and are reached only through `sample`, which returns f/pdf ratios consistent
//! with a discrete probability.

mod blinn_phong;
mod conductor;
mod dielectric;
pub mod fresnel;
mod glossy;
mod hanrahan_krueger;
pub mod kubelka_munk;
mod lambert;
mod metallic_roughness;
pub mod microfacet;
mod mirror;
mod oren_nayar;
mod phong;
mod rough_dielectric;
mod subsurface_exit;
mod thin_dielectric;
mod ward;

#[cfg(test)]
mod tests;

use glam::{Vec2, Vec3A};
use tessera_scene::{MaterialKind, Roughness};

use crate::spectrum::Spectrum;

pub use blinn_phong::{BlinnPhong, BlinnPhongLobe};
pub use conductor::Conductor;
pub use dielectric::SmoothDielectric;
pub use glossy::{GlossyLobe, WithDiffuse};
pub use hanrahan_krueger::HanrahanKrueger;
pub use lambert::Lambert;
pub use metallic_roughness::MetallicRoughness;
pub use microfacet::Microfacet;
pub use mirror::Mirror;
pub use oren_nayar::OrenNayar;
pub use phong::{Phong, PhongLobe};
pub use rough_dielectric::RoughDielectric;
pub use subsurface_exit::SubsurfaceExit;
pub use thin_dielectric::ThinDielectric;
pub use ward::{Ward, WardLobe};

/// Whether the path carries radiance (from the camera) or importance (from a light): BTDFs
/// scale by 1/η² only for radiance (Veach's thesis §5.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}

/// What kinds of scattering a BSDF has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BsdfFlags {
    pub reflection: bool,
    pub transmission: bool,
    /// Has a delta (perfectly specular) component.
    pub specular: bool,
    /// Has a component with a density (diffuse or glossy).
    pub smooth: bool,
    /// Has a diffuse (Lambertian or Oren–Nayar) component: where photon mapping gathers.
    pub diffuse: bool,
}

/// A direction sampled from a BSDF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3A,
    /// f(wo, wi); for delta lobes, the lobe's weight divided by |cos θi|.
    pub f: Spectrum,
    /// Solid-angle density, or the discrete probability of a delta lobe.
    pub pdf: f32,
    pub specular: bool,
    pub transmission: bool,
    /// Relative IOR across the interface crossed (1 for reflection).
    pub eta: f32,
}

impl BsdfSample {
    /// A non-delta reflection toward `wi`, with f and pdf taken from the BSDF's own `eval`
    /// and `pdf` (so MIS sees the density the sample was drawn with); `None` where the pdf
    /// is zero.
    #[inline]
    pub fn reflection<B: Bsdf + ?Sized>(
        bsdf: &B,
        wo: Vec3A,
        wi: Vec3A,
        mode: TransportMode,
    ) -> Option<Self> {
        let pdf = bsdf.pdf(wo, wi, mode);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: bsdf.eval(wo, wi, mode),
            pdf,
            specular: false,
            transmission: false,
            eta: 1.0,
        })
    }

    /// A delta reflection toward `wi` chosen with discrete probability `pdf`, carrying the
    /// lobe weight `weight` (f is weight/|cos θi|, per the convention above).
    #[inline]
    pub fn specular_reflection(wi: Vec3A, weight: Spectrum, pdf: f32) -> Self {
        BsdfSample {
            wi,
            f: weight / wi.z.abs(),
            pdf,
            specular: true,
            transmission: false,
            eta: 1.0,
        }
    }

    /// The throughput weight f·|cos θi| / pdf.
    #[inline]
    pub fn weight(&self) -> Spectrum {
        self.f * (self.wi.z.abs() / self.pdf)
    }
}

/// A BSDF in the local shading frame.
pub trait Bsdf: Send + Sync + std::fmt::Debug {
    fn flags(&self) -> BsdfFlags;
    /// f(wo, wi), zero for delta components.
    fn eval(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> Spectrum;
    /// Samples wi given wo; `u_lobe` picks a lobe, `u` the direction within it.
    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample>;
    /// Density with which `sample` produces wi (zero for delta components).
    fn pdf(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> f32;
    /// A representative reflectance (for the albedo AOV).
    fn albedo(&self) -> Spectrum;
    /// ρ if the BSDF is exactly Lambertian (f = ρ/π): the irradiance cache applies.
    fn lambertian(&self) -> Option<Spectrum> {
        None
    }
}

/// Builds the BSDF of a material description.
pub fn from_desc(kind: &MaterialKind) -> Box<dyn Bsdf> {
    let v = |c: glam::Vec3| Vec3A::from(c);
    match *kind {
        MaterialKind::Diffuse { albedo } => Box::new(Lambert::new(v(albedo))),
        MaterialKind::OrenNayar { albedo, sigma } => Box::new(OrenNayar::new(v(albedo), sigma)),
        MaterialKind::Phong {
            diffuse,
            specular,
            exponent,
        } => Box::new(Phong::new(
            v(diffuse),
            v(specular),
            PhongLobe::new(exponent),
        )),
        MaterialKind::BlinnPhong {
            diffuse,
            specular,
            exponent,
        } => Box::new(BlinnPhong::new(
            v(diffuse),
            v(specular),
            BlinnPhongLobe::new(exponent),
        )),
        MaterialKind::Ward {
            diffuse,
            specular,
            alpha_x,
            alpha_y,
        } => Box::new(Ward::new(
            v(diffuse),
            v(specular),
            WardLobe::new(alpha_x, alpha_y),
        )),
        MaterialKind::Conductor {
            eta,
            k,
            specular,
            roughness,
        } => Box::new(Conductor::new(
            v(eta),
            v(k),
            v(specular),
            microfacet_of(&roughness),
        )),
        MaterialKind::Dielectric {
            eta,
            roughness,
            tint,
            thin,
            ..
        } => {
            let tint = v(tint);
            let mf = microfacet_of(&roughness);
            match mf {
                _ if thin => Box::new(ThinDielectric::new(eta, mf).with_tint(tint)),
                Some(mf) if eta != 1.0 => Box::new(RoughDielectric::new(eta, mf).with_tint(tint)),
                _ => Box::new(SmoothDielectric::new(eta).with_tint(tint)),
            }
        }
        MaterialKind::Mirror { reflectance } => Box::new(Mirror::new(v(reflectance))),
        MaterialKind::MetallicRoughness { .. } => {
            Box::new(metallic_roughness_of(kind).expect("a metallic-roughness material"))
        }
        // The interface of a translucent object; what enters is the BSSRDF's (`bssrdf`).
        MaterialKind::Subsurface { eta, .. } => Box::new(SmoothDielectric::new(eta)),
        MaterialKind::KubelkaMunk {
            ref layers,
            substrate,
        } => Box::new(Lambert::new(kubelka_munk::reflectance(
            layers,
            v(substrate),
        ))),
        MaterialKind::HanrahanKrueger {
            sigma_s,
            sigma_a,
            thickness,
            g,
            eta,
            substrate,
        } => Box::new(HanrahanKrueger::new(
            v(sigma_s),
            v(sigma_a),
            thickness,
            g,
            eta,
            v(substrate),
        )),
    }
}

/// A direction for a diffuse lobe: cosine-weighted over the upper hemisphere (wo.z > 0 is the
/// caller's to check). Shared by every BSDF with a Lambertian part.
#[inline]
fn sample_diffuse(u: Vec2) -> Option<Vec3A> {
    let wi = crate::sampling::square_to_cosine_hemisphere(u);
    (wi.z > 0.0).then_some(wi)
}

/// Density of [`sample_diffuse`] for the pair (wo, wi): cos θi / π within the upper hemisphere.
#[inline]
fn diffuse_pdf(wo: Vec3A, wi: Vec3A) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        0.0
    } else {
        crate::sampling::cosine_hemisphere_pdf(wi.z)
    }
}

/// Density of a reflection sampled through a half vector: p(wi) = p_h(h) / (4 wo·h), with
/// h the normalised wo + wi (Walter et al. 2007, eq. 14). Zero where wo·h ≤ 0.
#[inline]
fn reflected_pdf(wo: Vec3A, wi: Vec3A, pdf_h: impl FnOnce(Vec3A) -> f32) -> f32 {
    let h = (wo + wi).normalize();
    let d = wo.dot(h);
    if d <= 0.0 { 0.0 } else { pdf_h(h) / (4.0 * d) }
}

/// The glTF BRDF of a metallic-roughness material, by its factors alone: textures are the
/// scene's to apply per hit (`scene::Material::bsdf_at`).
pub fn metallic_roughness_of(kind: &MaterialKind) -> Option<MetallicRoughness> {
    let MaterialKind::MetallicRoughness {
        base_color,
        metallic,
        roughness,
        ior,
        specular_color,
        specular,
        ref transmission,
        ..
    } = *kind
    else {
        return None;
    };
    Some(
        MetallicRoughness::new(
            base_color.into(),
            metallic,
            roughness,
            ior,
            specular_color.into(),
            specular,
        )
        .with_transmission(transmission),
    )
}

fn microfacet_of(r: &Roughness) -> Option<Microfacet> {
    (!r.is_smooth()).then(|| Microfacet::new(r.distribution, r.alpha_u, r.alpha_v))
}
