//! The one list of rendering methods: adding a method is its file and a line here. The CLI,
//! the bench, the farm's API and OpenAPI document, the coordinator and the worker all read it
//! (through [`super::lookup`] and [`super::names`]).

use super::info::MethodInfo;

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
