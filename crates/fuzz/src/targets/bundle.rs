//! `bundle`: a scene bundle as `POST /v1/bundles` receives it (a tar); one that is accepted
//! must pack again to a bundle of the same files.

use std::path::Path;

use tessera_farm::bundle::Bundle;

use crate::{Target, repo};

pub const TARGET: Target = Target {
    name: "bundle",
    about: "a bundle tar as uploaded: read, and what is read packs back to the same files",
    run,
    seeds,
};

fn run(data: &[u8]) -> bool {
    let Ok(bundle) = Bundle::from_tar(data) else {
        return false;
    };
    let tar = bundle.to_tar().expect("a bundle that was read packs again");
    let again = Bundle::from_tar(&tar).expect("a packed bundle reads back");
    assert_eq!(
        again.files, bundle.files,
        "a bundle's files change when packed again"
    );
    true
}

/// Bundles of example scenes, packed as `tessera submit` packs them.
fn seeds() -> Vec<(String, Vec<u8>)> {
    ["cornell-box", "depth-of-field", "cornell-glass"]
        .iter()
        .filter_map(|name| {
            let path = repo().join("scenes").join(name).join("scene.json");
            let (bundle, _, _) = Bundle::pack_scene(Path::new(&path)).ok()?;
            Some((format!("{name}.tar"), bundle.to_tar().ok()?))
        })
        .collect()
}
