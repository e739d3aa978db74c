//! Subsurface scattering: BSSRDF models of translucent materials (issue 7). So far the
//! dipole diffusion profile of Jensen et al. 2001 and its measured media; the hierarchical
//! evaluation, the sampled BSSRDF in the path tracer and the random-walk reference are to come.

pub mod dipole;
