//! The two Metropolis renderers behind one face (for `tessera render`, the bench and the
//! farm), and what they share: direct light and the brightness b by BDPT, bootstrap paths to
//! start chains from, and the cutting of a frame's work into [`GROUPS`].
//!
//! A frame's work is cut into [`GROUPS`] groups, each with its share of the direct-light
//! samples, of the brightness samples, of the bootstrap paths and of the chains (which start
//! from their own group's bootstrap). A group's result is fixed-point sums
//! ([`BdptSums`]: direct light, chain splats, brightness), so the frame is the same bits
//! whether its groups are rendered together or as separate farm tasks merged in any order.

pub mod mlt;
pub mod pssmlt;

mod chains;
mod primary;

use std::ops::Range;

pub use chains::{ChainSums, GROUPS, share};
use chains::{Chains, chain_groups, direct_light, render_groups};
use mlt::Mlt;
use pssmlt::Pssmlt;

use crate::SampleRange;
use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::RayStats;
use crate::integrator::bdpt::{BdptSums, Ctx};
use crate::scene::Scene;

/// A group of chains as [`Metropolis::chains`] renders it.
pub struct GroupWork {
    pub sums: ChainSums,
    pub stats: RayStats,
    /// Wall seconds of its work that grows neither with the film nor with the mutations: the
    /// fewest brightness samples and the bootstrap paths (more brightness samples come with
    /// a large budget; those are counted here too).
    pub fixed_s: f64,
}

#[derive(Debug, Clone, Copy)]
pub enum Metropolis {
    /// Primary sample space (Kelemen et al.), multiplexed.
    Pssmlt(Pssmlt),
    /// Path space (Veach & Guibas).
    Mlt(Mlt),
}

impl Metropolis {
    fn ctx<'a>(&self, scene: &'a Scene, camera: &'a Camera) -> Result<Ctx<'a>, String> {
        match self {
            Metropolis::Pssmlt(m) => m.ctx(scene, camera),
            Metropolis::Mlt(m) => m.ctx(scene, camera),
        }
    }

    fn max_depth(&self) -> u32 {
        match self {
            Metropolis::Pssmlt(m) => m.settings().max_depth,
            Metropolis::Mlt(m) => m.settings().max_depth,
        }
    }

    /// Direct light for samples `range` of every pixel (see [`direct_light`]): fixed-point
    /// sums, any split of the samples merging to the same bits.
    pub fn direct(
        &self,
        scene: &Scene,
        camera: &Camera,
        range: SampleRange,
    ) -> Result<(BdptSums, RayStats), String> {
        direct_light(&self.ctx(scene, camera)?, self.max_depth(), range)
    }

    /// Group `group` of the chains of a frame with `mutations` per pixel (its brightness
    /// samples, bootstrap paths and chains).
    pub fn chains(
        &self,
        scene: &Scene,
        camera: &Camera,
        mutations: u32,
        group: u32,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<GroupWork, String> {
        let ctx = self.ctx(scene, camera)?;
        let g = group..group + 1;
        let (sums, stats, fixed_s) = match self {
            Metropolis::Pssmlt(m) => chain_groups(m, &ctx, mutations, g, progress),
            Metropolis::Mlt(m) => chain_groups(m, &ctx, mutations, g, progress),
        };
        Ok(GroupWork {
            sums,
            stats,
            fixed_s,
        })
    }

    /// Groups `groups` of a frame with `mutations` per pixel (see [`GROUPS`]).
    pub fn render_groups(
        &self,
        scene: &Scene,
        camera: &Camera,
        mutations: u32,
        groups: Range<u32>,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(BdptSums, RayStats), String> {
        match self {
            Metropolis::Pssmlt(m) => render_groups(m, scene, camera, mutations, groups, progress),
            Metropolis::Mlt(m) => render_groups(m, scene, camera, mutations, groups, progress),
        }
    }

    /// Renders with `mutations` per pixel (every group) on the rayon pool; `progress` counts
    /// mutations.
    pub fn render(
        &self,
        scene: &Scene,
        camera: &Camera,
        mutations: u32,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(Image, RayStats), String> {
        let (sums, stats) = self.render_groups(scene, camera, mutations, 0..GROUPS, progress)?;
        Ok((sums.image(camera.exposure), stats))
    }

    pub fn name(&self) -> &'static str {
        match self {
            Metropolis::Pssmlt(_) => "pssmlt",
            Metropolis::Mlt(_) => "mlt",
        }
    }

    /// The settings, for logs and the EXR's metadata.
    pub fn describe(&self, mutations: u32) -> String {
        match self {
            Metropolis::Pssmlt(m) => format!(
                "{mutations} mutations per pixel, pssmlt ({} chains, {} bootstrap paths, σ {}, large steps {})",
                m.chains, m.bootstrap, m.sigma, m.large_step
            ),
            Metropolis::Mlt(m) => format!(
                "{mutations} mutations per pixel, mlt ({} chains from {} bootstrap paths; bidirectional, lens subpath, lens and caustic perturbation mutations)",
                m.chains, m.bootstrap
            ),
        }
    }
}
