//! The one list of rendering methods. The CLI, the bench, the farm's API and OpenAPI
//! document, the coordinator and the worker all read it; adding a method is its file and a
//! line here.

use super::{Job, Plan};

/// A method as users meet it: its name (`integrator.type`, `--integrator`), what it does, and
/// the settings it reads.
pub struct MethodInfo {
    pub name: &'static str,
    /// One line: what it is, after whom.
    pub summary: &'static str,
    /// What `spp` counts for it.
    pub spp: &'static str,
    /// Scene settings it reads besides `spp`, `max_depth`, `rr_depth` and `seed`.
    pub params: &'static [&'static str],
    /// Plans a job (the scene with the job's settings applied); errors name the setting and
    /// what was expected.
    pub plan: fn(&Job) -> Result<Box<dyn Plan>, String>,
}

/// Every method, in the order users see them.
pub static METHODS: &[&MethodInfo] = &[
    &super::path::PATH,
    &super::path::DIRECT,
    &super::auto::AUTO,
    &super::photon::PHOTON,
    &super::sppm::SPPM,
    &super::bdpt::BDPT,
    &super::vcm::VCM,
    &super::metropolis::PSSMLT,
    &super::metropolis::MLT,
];

/// Every method's name.
pub fn names() -> Vec<&'static str> {
    METHODS.iter().map(|m| m.name).collect()
}

/// The method called `name`.
pub fn lookup(name: &str) -> Result<&'static MethodInfo, String> {
    METHODS
        .iter()
        .copied()
        .find(|m| m.name == name.trim())
        .ok_or_else(|| {
            format!(
                "integrator.type: expected one of {}, got \"{name}\"",
                names().join(", ")
            )
        })
}

/// Plans `job` with the method its scene names.
pub fn plan(job: &Job) -> Result<Box<dyn Plan>, String> {
    (lookup(&job.desc.integrator.method)?.plan)(job)
}
