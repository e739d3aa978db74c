//! Subsurface transport in a scene: where light that entered a translucent object leaves it,
//! found by tracing rays against the object (the models themselves, scene-free, are in
//! [`crate::bssrdf`]).
//!
//! - [`probe`]: the sampled BSSRDF of the path tracer — exit points found by probe rays along
//!   three axes (pbrt-v3 §15.4, after Mertens et al.'s tangent-plane sampling);
//! - [`single`]: Jensen et al. 2001's single-scattering term, added by both dipole methods;
//! - [`hierarchical`]: Jensen & Buhler 2002 — irradiance on a point cloud, summed through an
//!   octree;
//! - [`walk`]: the brute-force reference, a volumetric random walk inside the object.

pub mod hierarchical;
pub mod probe;
pub mod single;
pub mod walk;
