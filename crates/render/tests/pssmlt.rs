//! Multiplexed primary-sample-space MLT is unbiased (up to its brightness estimate, whose
//! share of the budget grows with it): on the Cornell box and cornell-glass it converges to
//! the path-traced 32×32 references (`tests/photon.rs`), emitter pixels left out as there.

mod common;

#[test]
fn pssmlt_converges_to_the_path_traced_reference_the_same_on_any_threads() {
    common::assert_metropolis_converges_deterministically("pssmlt");
}
