//! The layouts of every payload that crosses processes or lies on disk, pinned to
//! [`wire::VERSION`].
//!
//! Payloads are postcard, which carries no field names: a worker of another build whose
//! struct lost or gained a field would decode a result into the wrong fields, not fail. So
//! a reader refuses another wire version, and this test makes the version change whenever a
//! layout does. It traces each payload type's serde format (`serde-reflection`) and compares
//! it with `tests/data/wire-layouts.json`, whose `versions` maps each wire version to the
//! digest of the layouts it was released with. A change of layout fails here until
//! `wire::VERSION` is bumped and the file is written again:
//!
//! ```text
//! TESSERA_BLESS_WIRE=1 cargo test --release -p tessera-render --lib wire_layouts
//! ```
//!
//! which refuses to pin new layouts to a version that already pins others.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::de::DeserializeOwned;
use serde_reflection::{Format, Registry, Tracer, TracerConfig};

use crate::wire;

/// The committed layouts.
fn file() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/wire-layouts.json")
}

fn trace<T: DeserializeOwned>(
    tracer: &mut Tracer,
    payloads: &mut BTreeMap<String, Format>,
    name: &str,
) {
    let (format, _) = tracer
        .trace_simple_type::<T>()
        .unwrap_or_else(|e| panic!("tracing {name}: {e}"));
    payloads.insert(name.to_string(), format);
}

/// Every payload type by what carries it, and the formats of the types they hold.
fn layouts() -> (BTreeMap<String, Format>, Registry) {
    let mut tracer = Tracer::new(TracerConfig::default());
    let mut p = BTreeMap::new();
    let t = &mut tracer;
    // Task results and frame states (checkpoints) of the frame methods.
    trace::<super::tiles::TilePartial>(t, &mut p, "path, direct, photon: task result");
    trace::<super::tiles::TileFrame>(t, &mut p, "path, direct, photon: frame");
    trace::<super::ranges::RangePartial>(t, &mut p, "bdpt, vcm: task result");
    trace::<super::ranges::RangeFrame>(t, &mut p, "bdpt, vcm: frame");
    trace::<super::sppm::SppmPartial>(t, &mut p, "sppm: task result");
    trace::<super::sppm::SppmFrame>(t, &mut p, "sppm: frame");
    trace::<Vec<f32>>(t, &mut p, "sppm: step input (squared radii)");
    trace::<super::metropolis::MetroPartial>(t, &mut p, "pssmlt, mlt: task result");
    trace::<super::metropolis::MetroFrame>(t, &mut p, "pssmlt, mlt: frame");
    // Checkpoints lead with the step's number.
    trace::<u32>(t, &mut p, "checkpoint: step");
    // The passes: task results and artifacts.
    trace::<Vec<crate::photon::Photon>>(t, &mut p, "photons: task result");
    trace::<super::passes::photons::MapsArtifact>(t, &mut p, "photons: artifact");
    trace::<Vec<crate::irradiance::Record>>(t, &mut p, "records: task result, artifact");
    trace::<Vec<[f32; 3]>>(t, &mut p, "subsurface: task result, artifact");
    let registry = tracer
        .registry()
        .unwrap_or_else(|e| panic!("an incomplete layout: {e}"));
    (p, registry)
}

/// The committed file: wire version → digest, and the current version's layouts.
#[derive(serde::Serialize, serde::Deserialize)]
struct Pinned {
    about: String,
    versions: BTreeMap<u16, String>,
    payloads: BTreeMap<String, Format>,
    types: Registry,
}

#[test]
fn wire_layouts_are_pinned_to_the_wire_version() {
    let (payloads, types) = layouts();
    let text = serde_json::to_string(&(&payloads, &types)).expect("layouts serialise");
    let digest = format!("{:08x}", crc32fast::hash(text.as_bytes()));
    let path = file();
    let read = std::fs::read_to_string(&path)
        .map_err(|e| e.to_string())
        .and_then(|s| serde_json::from_str::<Pinned>(&s).map_err(|e| e.to_string()));
    if std::env::var_os("TESSERA_BLESS_WIRE").is_some() {
        let mut versions = read.map(|p| p.versions).unwrap_or_default();
        if let Some(old) = versions.get(&wire::VERSION).filter(|d| **d != digest) {
            panic!(
                "wire::VERSION {} already pins layouts {old}; these are {digest}: bump wire::VERSION (crates/render/src/wire.rs) first",
                wire::VERSION
            );
        }
        versions.insert(wire::VERSION, digest);
        let pinned = Pinned {
            about: "Payload layouts of each wire version (crates/render/src/method/layouts.rs); written by TESSERA_BLESS_WIRE=1 cargo test -p tessera-render --lib wire_layouts".into(),
            versions,
            payloads,
            types,
        };
        let json = serde_json::to_string_pretty(&pinned).expect("layouts serialise");
        std::fs::write(&path, json + "\n").unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        return;
    }
    let pinned = read.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let changed: Vec<&String> = payloads
        .iter()
        .filter(|(name, f)| pinned.payloads.get(*name) != Some(*f))
        .map(|(name, _)| name)
        .chain(
            types
                .iter()
                .filter(|(name, f)| pinned.types.get(*name) != Some(*f))
                .map(|(name, _)| name),
        )
        .collect();
    assert!(
        pinned.versions.get(&wire::VERSION) == Some(&digest) && changed.is_empty(),
        "payload layouts ({digest}) are not those {} pins for wire version {} ({:?}); changed: {changed:?}. \
         A process of the other layout would decode them into the wrong fields: bump wire::VERSION \
         (crates/render/src/wire.rs), then TESSERA_BLESS_WIRE=1 cargo test -p tessera-render --lib wire_layouts",
        path.display(),
        wire::VERSION,
        pinned.versions.get(&wire::VERSION),
    );
}
