//! What a method says about itself, for users and for the code that plans jobs.

use super::{Job, Plan};

/// A method as users meet it: its name (`integrator.type`, `--integrator`), what it does, and
/// the settings it reads; and what planning needs to know of it before it runs.
pub struct MethodInfo {
    pub name: &'static str,
    /// One line: what it is, after whom.
    pub summary: &'static str,
    /// What `spp` counts for it.
    pub spp: &'static str,
    /// Scene settings it reads besides `spp`, `max_depth`, `rr_depth` and `seed`.
    pub params: &'static [&'static str],
    /// Whether it renders translucent (subsurface) materials; a job of a scene that has them
    /// is refused for a method that does not, before it is planned.
    pub translucent: bool,
    /// Plans a job (the scene with the job's settings applied); errors name the setting and
    /// what was expected. Called through [`super::plan_as`], which refuses first what the
    /// method cannot render.
    pub plan: fn(&Job) -> Result<Box<dyn Plan>, String>,
}
