//! The one list of rendering methods: adding a method is its file and a line here. The CLI,
//! the bench, the farm's API and OpenAPI document, the coordinator, the worker and `auto`'s
//! pilot all read it (through [`methods`], [`super::lookup`] and [`super::names`]).

use std::sync::{PoisonError, RwLock};

use super::info::MethodInfo;

/// Every method built in, in the order users see them.
static BUILT_IN: &[&MethodInfo] = &[
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

/// The methods built in (without those registered).
#[cfg(test)]
pub(super) fn built_in() -> &'static [&'static MethodInfo] {
    BUILT_IN
}

/// Methods registered by the program after it started (a plug-in, a test's method).
static REGISTERED: RwLock<Vec<&'static MethodInfo>> = RwLock::new(Vec::new());

/// Every method: the built-in ones, then those registered, in registration order.
pub fn methods() -> Vec<&'static MethodInfo> {
    let registered = REGISTERED.read().unwrap_or_else(PoisonError::into_inner);
    BUILT_IN
        .iter()
        .copied()
        .chain(registered.iter().copied())
        .collect()
}

/// Adds `method` to the registry of this process: planned, listed, measured by `auto` and run
/// by a worker as the built-in ones are. Every process of a farm that runs its jobs must
/// register it too. Refuses a name already taken.
pub fn register(method: &'static MethodInfo) -> Result<(), String> {
    let mut registered = REGISTERED.write().unwrap_or_else(PoisonError::into_inner);
    if BUILT_IN
        .iter()
        .chain(registered.iter())
        .any(|m| m.name == method.name)
    {
        return Err(format!("method {}: the name is taken", method.name));
    }
    registered.push(method);
    Ok(())
}
