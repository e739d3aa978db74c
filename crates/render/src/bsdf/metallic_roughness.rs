//! The glTF 2.0 metallic-roughness BRDF (glTF 2.0 specification, appendix B; with
//! KHR_materials_ior and KHR_materials_specular): a dielectric — a Lambertian base under a GGX
//! specular layer, mixed by Schlick's Fresnel — blended with a metal by `metallic`:
//!
//! f = (1 − m) [c/π · (1 − E(θo))(1 − E(θi)) / (1 − E_avg) + w·F_d(wo·h)·S] + m·F_m(wo·h)·S,
//! S = D(h) G(wo, wi) / (4 cos θo cos θi),
//! F_d(x) = f0 + (1 − f0)(1 − x)⁵ with f0 = ((η − 1)/(η + 1))² · specular colour,
//! F_m(x) = c + (1 − c)(1 − x)⁵,
//! E(θ) = the dielectric layer's directional albedo w·∫ max F_d · S cos θi dωi (tabulated),
//! E_avg = 2∫E(θ) cos θ d(cos θ),
//!
//! with c the base colour, m metallic, w the specular weight, α = roughness² (GGX, Smith
//! height-correlated G).
//!
//! One departure from appendix B: it weights the diffuse base by 1 − w·max F_d(wo·h), which
//! with a white base reflects more than it receives at oblique angles. Here the base is
//! weighted by the light the layer lets through on the way in and on the way out, normalised
//! so that a white base under the layer reflects exactly what it receives (Kelemen &
//! Szirmay-Kalos 2001's coupling, as in Kulla & Conty 2017). Every term is symmetric in wo and wi, so f is
//! reciprocal. Sampled as a mixture of the visible-normal GGX lobe and a cosine lobe, chosen
//! by their estimated weights at wo.
//!
//! Transmission (KHR_materials_transmission, KHR_materials_diffuse_transmission): the
//! specification mixes the dielectric's base, fresnel_mix(base, layer), with base =
//! mix(diffuse, specular BTDF, T). fresnel_mix is linear in its base, so this is
//! (1 − T)·[the opaque dielectric above] + T·[the layer over a specular BTDF], and the second
//! is a rough dielectric interface (Walter et al. 2007, exact Fresnel) with its transmission
//! tinted by the base colour — or, thin-walled, a rough thin sheet that does not bend light.
//! Diffuse transmission moves a share D of the coupled diffuse base to the other side with its
//! own colour: f = c_t/π · D · (coupling at |cos θo|, |cos θi|) for wi across the surface. With
//! transmission the BSDF is two-sided in its reflection lobes (the material keeps its frame
//! outward, so wo may lie below) and the interface sees which side light comes from.

use glam::{Vec2, Vec3A};
use tessera_scene::Distribution;

use super::microfacet::Microfacet;
use super::{
    Bsdf, BsdfFlags, BsdfSample, RoughDielectric, ThinDielectric, TransportMode, diffuse_pdf,
    reflected_pdf, sample_diffuse,
};
use crate::math::{INV_PI, reflect};
use crate::spectrum::{Spectrum, luminance};
use std::sync::OnceLock;

/// Smallest GGX width: below it the lobe is a mirror for every purpose and only its density's
/// float range would suffer.
const MIN_ALPHA: f32 = 1e-3;

#[derive(Debug, Clone)]
pub struct MetallicRoughness {
    base_color: Spectrum,
    metallic: f32,
    /// Dielectric reflectance at normal incidence (per channel, at most 1).
    f0: Spectrum,
    /// Specular weight w (KHR_materials_specular's `specularFactor`; 1 without it).
    specular: f32,
    /// Perceptual roughness, for the layer's albedo table.
    roughness: f32,
    microfacet: Microfacet,
    /// Share T of the dielectric base that is specular transmission.
    transmission: f32,
    /// Share D of the diffuse base transmitted diffusely, and its colour.
    diffuse_transmission: f32,
    diffuse_transmission_color: Spectrum,
    ior: f32,
    /// A thin wall: specular transmission through a sheet, not into an interior.
    thin: bool,
}

/// The interface of the transmitted share, built where it is evaluated.
enum Interface {
    Solid(RoughDielectric),
    Thin(ThinDielectric),
}

impl Interface {
    fn bsdf(&self) -> &dyn Bsdf {
        match self {
            Interface::Solid(b) => b,
            Interface::Thin(b) => b,
        }
    }
}

/// Lobe selection probabilities at one wo: specular layer (with metal), diffuse reflection,
/// diffuse transmission, transmitting interface.
#[derive(Clone, Copy)]
struct Lobes {
    specular: f32,
    diffuse: f32,
    diffuse_transmission: f32,
    interface: f32,
}

/// `w` mirrored through the surface plane.
#[inline]
fn mirror(w: Vec3A) -> Vec3A {
    Vec3A::new(w.x, w.y, -w.z)
}

/// Cells of [`LayerTable`] along cos θ and along roughness.
const TABLE_N: usize = 48;
/// Stratified samples per side for each cell's estimate.
const TABLE_SAMPLES: usize = 64;

/// The GGX layer's directional albedo as a function of cos θ and perceptual roughness, for a
/// Fresnel weight of 1 (`e1`) and of Schlick's (1 − wo·h)⁵ (`es`): Schlick's F is linear in
/// f0, so E = f0·e1 + (1 − f0)·es for any f0. Estimated once per process, deterministically,
/// by stratified visible-normal sampling (weight G/G₁ per sample).
struct LayerTable {
    e1: Vec<f32>,
    es: Vec<f32>,
    /// 2∫E cos θ d(cos θ) per roughness.
    avg1: Vec<f32>,
    avgs: Vec<f32>,
}

impl LayerTable {
    fn get() -> &'static LayerTable {
        static TABLE: OnceLock<LayerTable> = OnceLock::new();
        TABLE.get_or_init(LayerTable::build)
    }

    fn build() -> LayerTable {
        let n = TABLE_N;
        let (mut e1, mut es) = (vec![0.0; n * n], vec![0.0; n * n]);
        for j in 0..n {
            let r = j as f32 / (n - 1) as f32;
            let a = (r * r).max(MIN_ALPHA);
            let mf = Microfacet::new(Distribution::Ggx, a, a);
            for i in 0..n {
                let mu = (i as f32 / (n - 1) as f32).max(1e-3);
                let wo = Vec3A::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let (mut s1, mut ss) = (0.0f64, 0.0f64);
                for k in 0..TABLE_SAMPLES * TABLE_SAMPLES {
                    let u = Vec2::new(
                        ((k % TABLE_SAMPLES) as f32 + 0.5) / TABLE_SAMPLES as f32,
                        ((k / TABLE_SAMPLES) as f32 + 0.5) / TABLE_SAMPLES as f32,
                    );
                    let m = mf.sample_m(wo, u);
                    let wi = reflect(wo, m);
                    if wi.z <= 0.0 || wo.dot(m) <= 0.0 {
                        continue;
                    }
                    let w = (mf.g(wo, wi) / mf.g1(wo)) as f64;
                    s1 += w;
                    ss += w * MetallicRoughness::schlick(wo.dot(m)) as f64;
                }
                let count = (TABLE_SAMPLES * TABLE_SAMPLES) as f64;
                e1[j * n + i] = (s1 / count) as f32;
                es[j * n + i] = (ss / count) as f32;
            }
        }
        // 2∫E μ dμ of E as [`Self::albedo`] interpolates it (linear in μ within each cell),
        // exactly, so that the coupled base reflects what the table says the layer passes.
        let avg = |e: &[f32], j: usize| {
            let h = 1.0 / (n - 1) as f64;
            (0..n - 1)
                .map(|i| {
                    let (a, b) = (e[j * n + i] as f64, e[j * n + i + 1] as f64);
                    let x0 = i as f64 * h;
                    // ∫ μ (a + (b − a)(μ − x0)/h) dμ over [x0, x0 + h].
                    a * (x0 * h + h * h / 2.0) + (b - a) * (x0 * h / 2.0 + h * h / 3.0)
                })
                .sum::<f64>() as f32
                * 2.0
        };
        let avg1 = (0..n).map(|j| avg(&e1, j)).collect();
        let avgs = (0..n).map(|j| avg(&es, j)).collect();
        LayerTable { e1, es, avg1, avgs }
    }

    /// Bilinear (e1, es) at cos θ `mu` and roughness `r`.
    fn albedo(&self, mu: f32, r: f32) -> (f32, f32) {
        let n = TABLE_N;
        let (x, y) = (
            mu.clamp(0.0, 1.0) * (n - 1) as f32,
            r.clamp(0.0, 1.0) * (n - 1) as f32,
        );
        let (i, j) = ((x as usize).min(n - 2), (y as usize).min(n - 2));
        let (fx, fy) = (x - i as f32, y - j as f32);
        let lerp2 = |t: &[f32]| {
            let a = t[j * n + i] * (1.0 - fx) + t[j * n + i + 1] * fx;
            let b = t[(j + 1) * n + i] * (1.0 - fx) + t[(j + 1) * n + i + 1] * fx;
            a * (1.0 - fy) + b * fy
        };
        (lerp2(&self.e1), lerp2(&self.es))
    }

    /// (2∫e1 μ dμ, 2∫es μ dμ) at roughness `r`.
    fn average(&self, r: f32) -> (f32, f32) {
        let n = TABLE_N;
        let y = r.clamp(0.0, 1.0) * (n - 1) as f32;
        let j = (y as usize).min(n - 2);
        let f = y - j as f32;
        let lerp = |t: &[f32]| t[j] * (1.0 - f) + t[j + 1] * f;
        (lerp(&self.avg1), lerp(&self.avgs))
    }
}

impl MetallicRoughness {
    /// `roughness` is glTF's perceptual roughness (α = roughness²); `ior` the dielectric's
    /// index of refraction (1.5 in core glTF); `specular_color` and `specular` as in
    /// KHR_materials_specular (white and 1 without it).
    pub fn new(
        base_color: Spectrum,
        metallic: f32,
        roughness: f32,
        ior: f32,
        specular_color: Spectrum,
        specular: f32,
    ) -> Self {
        let r = ((ior - 1.0) / (ior + 1.0)).powi(2);
        let alpha = (roughness * roughness).max(MIN_ALPHA);
        MetallicRoughness {
            base_color,
            metallic: metallic.clamp(0.0, 1.0),
            f0: (specular_color * r).min(Spectrum::ONE),
            specular: specular.clamp(0.0, 1.0),
            roughness: roughness.clamp(0.0, 1.0),
            microfacet: Microfacet::new(Distribution::Ggx, alpha, alpha),
            transmission: 0.0,
            diffuse_transmission: 0.0,
            diffuse_transmission_color: Spectrum::ONE,
            ior,
            thin: false,
        }
    }

    /// This BSDF letting light through as `t` says (KHR_materials_transmission and
    /// KHR_materials_diffuse_transmission).
    pub fn with_transmission(self, t: &tessera_scene::PbrTransmission) -> Self {
        MetallicRoughness {
            transmission: t.specular.clamp(0.0, 1.0),
            diffuse_transmission: t.diffuse.clamp(0.0, 1.0),
            diffuse_transmission_color: Spectrum::from(t.diffuse_color)
                .clamp(Spectrum::ZERO, Spectrum::ONE),
            thin: t.thin,
            ..self
        }
    }

    /// Weight of the opaque dielectric (coupled diffuse base and its layer): (1 − m)(1 − T).
    #[inline]
    fn opaque(&self) -> f32 {
        (1.0 - self.metallic) * (1.0 - self.transmission)
    }

    /// Weight of the transmitting interface: (1 − m) T.
    #[inline]
    fn interface_weight(&self) -> f32 {
        (1.0 - self.metallic) * self.transmission
    }

    /// The transmitting interface (rough at this BRDF's α), its transmission tinted by the
    /// base colour.
    #[inline]
    fn interface(&self) -> Interface {
        if self.thin {
            Interface::Thin(
                ThinDielectric::new(self.ior, Some(self.microfacet)).with_tint(self.base_color),
            )
        } else {
            Interface::Solid(
                RoughDielectric::new(self.ior, self.microfacet).with_tint(self.base_color),
            )
        }
    }

    /// This BRDF with its base colour, metalness and roughness multiplied by `base`,
    /// `metallic` and `roughness` (texture values, each in [0, 1]).
    pub fn scaled(&self, base: Spectrum, metallic: f32, roughness: f32) -> Self {
        let roughness = (self.roughness * roughness).clamp(0.0, 1.0);
        let alpha = (roughness * roughness).max(MIN_ALPHA);
        MetallicRoughness {
            base_color: (self.base_color * base).clamp(Spectrum::ZERO, Spectrum::ONE),
            metallic: (self.metallic * metallic).clamp(0.0, 1.0),
            roughness,
            microfacet: Microfacet::new(Distribution::Ggx, alpha, alpha),
            ..self.clone()
        }
    }

    /// Schlick's (1 − cos)⁵.
    #[inline]
    fn schlick(cos: f32) -> f32 {
        let c = (1.0 - cos).clamp(0.0, 1.0);
        let c2 = c * c;
        c2 * c2 * c
    }

    /// The specular layer's Fresnel weight at cosine `cos` between wo and the half vector.
    #[inline]
    fn specular_weight(&self, cos: f32) -> Spectrum {
        let s = Self::schlick(cos);
        let fd = self.f0 + (Spectrum::ONE - self.f0) * s;
        let fm = self.base_color + (Spectrum::ONE - self.base_color) * s;
        let m = self.metallic;
        self.opaque() * self.specular * fd + m * fm
    }

    /// E(θ): the share of light the dielectric layer reflects at cosine `cos`.
    #[inline]
    fn layer(&self, cos: f32) -> f32 {
        let f0 = self.f0.max_element();
        let (e1, es) = LayerTable::get().albedo(cos, self.roughness);
        self.specular * (f0 * e1 + (1.0 - f0) * es)
    }

    /// The diffuse base's weight for the cosines of wo and wi (multiplies c/π), reflected and
    /// transmitted together.
    #[inline]
    fn diffuse_weight(&self, cos_o: f32, cos_i: f32) -> f32 {
        let f0 = self.f0.max_element();
        let (a1, a_s) = LayerTable::get().average(self.roughness);
        let avg = self.specular * (f0 * a1 + (1.0 - f0) * a_s);
        self.opaque() * (1.0 - self.layer(cos_o)) * (1.0 - self.layer(cos_i))
            / (1.0 - avg).max(1e-4)
    }

    /// Lobe probabilities at wo (above the surface): the layer's reflectance there against
    /// the base's albedo under it, split between its parts.
    #[inline]
    fn lobes(&self, wo: Vec3A) -> Lobes {
        let s = luminance(self.specular_weight(wo.z));
        let base = self.opaque() * (1.0 - self.layer(wo.z));
        let d = base * luminance(self.base_color) * (1.0 - self.diffuse_transmission);
        let dt = base * luminance(self.diffuse_transmission_color) * self.diffuse_transmission;
        let g = self.interface_weight();
        let total = s + d + dt + g;
        if dt == 0.0 && g == 0.0 {
            // Opaque: the layer or the diffuse base.
            let specular = if s + d > 0.0 { s / (s + d) } else { 1.0 };
            Lobes {
                specular,
                diffuse: 1.0 - specular,
                diffuse_transmission: 0.0,
                interface: 0.0,
            }
        } else if total > 0.0 {
            Lobes {
                specular: s / total,
                diffuse: d / total,
                diffuse_transmission: dt / total,
                interface: g / total,
            }
        } else {
            Lobes {
                specular: 1.0,
                diffuse: 0.0,
                diffuse_transmission: 0.0,
                interface: 0.0,
            }
        }
    }

    /// The reflection lobes (layer, metal, diffuse reflection) and diffuse transmission for
    /// wo above the surface.
    #[inline]
    fn eval_upper(&self, wo: Vec3A, wi: Vec3A) -> Spectrum {
        if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            let mf = &self.microfacet;
            let s = mf.d(h) * mf.g(wo, wi) / (4.0 * wo.z * wi.z);
            let diffuse = if self.diffuse_transmission > 0.0 {
                self.base_color * (1.0 - self.diffuse_transmission)
            } else {
                self.base_color
            };
            diffuse * (self.diffuse_weight(wo.z, wi.z) * INV_PI)
                + self.specular_weight(wo.dot(h)) * s
        } else if self.diffuse_transmission > 0.0 && wi.z < 0.0 {
            self.diffuse_transmission_color
                * (self.diffuse_transmission * self.diffuse_weight(wo.z, -wi.z) * INV_PI)
        } else {
            Spectrum::ZERO
        }
    }

    /// Density of the reflection lobes and diffuse transmission for wo above the surface.
    #[inline]
    fn pdf_upper(&self, p: &Lobes, wo: Vec3A, wi: Vec3A) -> f32 {
        if wi.z > 0.0 {
            let spec = reflected_pdf(wo, wi, |h| self.microfacet.pdf_m(wo, h));
            p.specular * spec + p.diffuse * diffuse_pdf(wo, wi)
        } else if wi.z < 0.0 {
            p.diffuse_transmission * diffuse_pdf(wo, mirror(wi))
        } else {
            0.0
        }
    }
}

impl Bsdf for MetallicRoughness {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: true,
            transmission: self.transmission > 0.0 || self.diffuse_transmission > 0.0,
            smooth: true,
            diffuse: self.metallic < 1.0 && self.base_color.max_element() > 0.0,
            ..Default::default()
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> Spectrum {
        if !self.flags().transmission {
            if wo.z <= 0.0 || wi.z <= 0.0 {
                return Spectrum::ZERO;
            }
            return self.eval_upper(wo, wi);
        }
        let mut f = if wo.z < 0.0 {
            self.eval_upper(mirror(wo), mirror(wi))
        } else {
            self.eval_upper(wo, wi)
        };
        if self.transmission > 0.0 {
            f += self.interface().bsdf().eval(wo, wi, mode) * self.interface_weight();
        }
        f
    }

    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let transmits = self.flags().transmission;
        if wo.z == 0.0 || (wo.z < 0.0 && !transmits) {
            return None;
        }
        // The reflection lobes are sampled above the surface, then turned back.
        let below = wo.z < 0.0;
        let up = if below { mirror(wo) } else { wo };
        let p = self.lobes(up);
        let mut eta = 1.0;
        let wi = if u_lobe < p.specular {
            let m = self.microfacet.sample_m(up, u);
            let wi = reflect(up, m);
            if up.dot(m) <= 0.0 || wi.z <= 0.0 {
                return None;
            }
            wi
        } else if !transmits || u_lobe < p.specular + p.diffuse {
            sample_diffuse(u)?
        } else if u_lobe < p.specular + p.diffuse + p.diffuse_transmission {
            mirror(sample_diffuse(u)?)
        } else {
            // The interface samples in the true frame, with its own lobe choice.
            let start = p.specular + p.diffuse + p.diffuse_transmission;
            let u_interface = ((u_lobe - start) / p.interface.max(f32::MIN_POSITIVE)).min(1.0);
            let s = self.interface().bsdf().sample(wo, u_interface, u, mode)?;
            eta = s.eta;
            if below { mirror(s.wi) } else { s.wi }
        };
        let wi = if below { mirror(wi) } else { wi };
        if wi.z == 0.0 || (!transmits && wi.z < 0.0) {
            return None;
        }
        let pdf = self.pdf(wo, wi, mode);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf,
            specular: false,
            transmission: wi.z * wo.z < 0.0,
            eta: if wi.z * wo.z < 0.0 { eta } else { 1.0 },
        })
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> f32 {
        if !self.flags().transmission {
            if wo.z <= 0.0 || wi.z <= 0.0 {
                return 0.0;
            }
            let p = self.lobes(wo);
            return self.pdf_upper(&p, wo, wi);
        }
        if wo.z == 0.0 {
            return 0.0;
        }
        let (up, wi_up) = if wo.z < 0.0 {
            (mirror(wo), mirror(wi))
        } else {
            (wo, wi)
        };
        let p = self.lobes(up);
        let mut pdf = self.pdf_upper(&p, up, wi_up);
        if p.interface > 0.0 {
            pdf += p.interface * self.interface().bsdf().pdf(wo, wi, mode);
        }
        pdf
    }

    fn albedo(&self) -> Spectrum {
        self.base_color
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::hash::{mix64, u32_to_unit};

    /// Albedo at `wo` (largest channel) by importance sampling with a fixed seed.
    fn albedo(b: &MetallicRoughness, wo: Vec3A) -> f32 {
        let n = 200_000u64;
        let u = |i: u64| u32_to_unit(mix64(i) as u32);
        let mut sum = 0.0f64;
        for i in 0..n {
            let s = b.sample(
                wo,
                u(3 * i),
                Vec2::new(u(3 * i + 1), u(3 * i + 2)),
                TransportMode::Radiance,
            );
            sum += s.map_or(0.0, |s| s.weight().max_element() as f64);
        }
        (sum / n as f64) as f32
    }

    #[test]
    fn a_white_dielectric_keeps_nearly_all_light_at_every_angle() {
        // The furnace suite checks the upper bound; this is the lower: the coupled base must
        // not darken what the layer lets through (only the GGX layer's single-scattering
        // loss, small at this roughness, may be missing).
        let b = MetallicRoughness::new(Spectrum::ONE, 0.0, 0.3, 1.5, Spectrum::ONE, 1.0);
        for deg in [0f32, 30.0, 60.0, 80.0] {
            let (s, c) = deg.to_radians().sin_cos();
            let a = albedo(&b, Vec3A::new(s, 0.0, c));
            assert!(a > 0.95 && a <= 1.005, "albedo {a} at {deg}°");
        }
    }

    #[test]
    fn the_layer_table_matches_a_smooth_interface_and_loses_energy_when_rough() {
        let t = LayerTable::get();
        // Smooth: the layer reflects exactly Schlick's Fresnel, e1 = 1 and es = (1 − μ)⁵.
        for mu in [0.2f32, 0.5, 1.0] {
            let (e1, es) = t.albedo(mu, 0.0);
            assert!((e1 - 1.0).abs() < 0.01, "e1 {e1} at μ {mu}");
            assert!(
                (es - MetallicRoughness::schlick(mu)).abs() < 0.01,
                "es {es} at μ {mu}"
            );
        }
        // Rough and grazing: single scattering loses light.
        assert!(t.albedo(0.1, 1.0).0 < 0.8);
    }
}
