//! Subsurface scattering: BSSRDF models of translucent materials (issue 7). So far the
//! dipole diffusion profile of Jensen et al. 2001 and its measured media, and the brute-force
//! random walk it is checked against on a slab; the hierarchical evaluation and the sampled
//! BSSRDF in the path tracer are to come.

pub mod dipole;
pub mod random_walk;
