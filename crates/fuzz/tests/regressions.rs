//! Every fuzz target takes its seeds and every input that once made it fail
//! (`regressions/NAME/`) without a panic; and reaches past its first check on some of its
//! seeds (a target that refuses everything fuzzes nothing).

#[test]
fn every_target_takes_its_seeds_and_its_regressions() {
    for t in tessera_fuzz::TARGETS {
        let seeds = (t.seeds)();
        assert!(!seeds.is_empty(), "{}: no seeds", t.name);
        let accepted: Vec<&str> = seeds
            .iter()
            .filter(|(_, bytes)| (t.run)(bytes))
            .map(|(name, _)| name.as_str())
            .collect();
        assert!(
            !accepted.is_empty(),
            "{}: none of its {} seeds is accepted",
            t.name,
            seeds.len()
        );
        for (name, bytes) in tessera_fuzz::regressions(t.name) {
            let _ = std::panic::catch_unwind(|| (t.run)(&bytes))
                .unwrap_or_else(|_| panic!("{}: regression {name} fails again", t.name));
        }
    }
}
