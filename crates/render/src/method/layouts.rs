//! The layouts of every payload that crosses processes or lies on disk, pinned to
//! [`wire::VERSION`].
//!
//! Payloads are postcard, which carries no field names: a worker of another build whose
//! struct lost or gained a field would decode a result into the wrong fields, not fail. So
//! a reader refuses another wire version, and this module's test makes the version change
//! whenever a layout does. Each method declares its payload types in its [`MethodInfo`]
//! (`payloads`: its frame method's task results and frame states, its steps' inputs, its
//! passes' results and artifacts, named by their types, so a declaration cannot be wrong
//! about a layout); the test traces each one's serde format (`serde-reflection`) and compares
//! them with `tests/data/wire-layouts.json`, whose `versions` maps each wire version to the
//! digest of the layouts it was released with. A change of layout fails there until
//! `wire::VERSION` is bumped and the file is written again:
//!
//! ```text
//! TESSERA_BLESS_WIRE=1 cargo test --release -p tessera-render --lib wire_layouts
//! ```
//!
//! which refuses to pin new layouts to a version that already pins others.

use serde::de::DeserializeOwned;

#[cfg(doc)]
use super::info::MethodInfo;
use super::{Method, Pass};

/// The carrier of a method's own payloads, which the layouts name by the methods that declare
/// them (a pass's are named by its label).
const OWN: &str = "";

/// The payload types a method writes, as its [`MethodInfo`] declares them. Only the layouts
/// test reads the declarations.
#[derive(Default)]
pub struct Payloads {
    #[cfg(test)]
    entries: Vec<tests::Entry>,
}

impl Payloads {
    /// The task results and frame states of frame method `M`.
    pub fn method<M: Method>(&mut self) -> &mut Self {
        self.add::<M::Partial>(OWN, "task result");
        self.add::<M::Frame>(OWN, "frame")
    }

    /// What a step of its frames reads besides the artifacts: `what`, of type `T`.
    pub fn input<T: DeserializeOwned + 'static>(&mut self, what: &'static str) -> &mut Self {
        self.add::<T>(OWN, what)
    }

    /// The task results and artifact of pass `P`, which the layouts call `label`.
    pub fn pass<P: Pass>(&mut self, label: &'static str) -> &mut Self {
        self.add::<P::Partial>(label, "task result");
        self.add::<P::Artifact>(label, "artifact")
    }

    #[cfg_attr(not(test), allow(unused_variables))]
    fn add<T: DeserializeOwned + 'static>(
        &mut self,
        carrier: &'static str,
        what: &'static str,
    ) -> &mut Self {
        #[cfg(test)]
        self.entries.push(tests::Entry::of::<T>(carrier, what));
        self
    }
}

#[cfg(test)]
mod tests {
    use std::any::TypeId;
    use std::collections::BTreeMap;
    use std::path::PathBuf;

    use serde::de::DeserializeOwned;
    use serde_reflection::{Format, Registry, Tracer, TracerConfig};

    use super::Payloads;
    use crate::wire;

    /// One declared payload: who carries it, what it is, its type and how to trace it.
    #[derive(Clone, Copy)]
    pub(super) struct Entry {
        carrier: &'static str,
        what: &'static str,
        ty: TypeId,
        trace: fn(&mut Tracer) -> serde_reflection::Result<Format>,
    }

    impl Entry {
        pub(super) fn of<T: DeserializeOwned + 'static>(
            carrier: &'static str,
            what: &'static str,
        ) -> Self {
            Entry {
                carrier,
                what,
                ty: TypeId::of::<T>(),
                trace: |t| t.trace_simple_type::<T>().map(|(f, _)| f),
            }
        }
    }

    /// The committed layouts.
    fn file() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/wire-layouts.json")
    }

    /// Every payload type by what carries it, and the formats of the types they hold: each
    /// built-in method's declarations ([`super::super::info::MethodInfo::payloads`]), a payload
    /// named by the methods that declare it (`path, direct, photon: task result`) or by its pass
    /// (`photons: artifact`), a type that is two payloads of one carrier named once for both
    /// (`records: task result, artifact`).
    fn layouts() -> (BTreeMap<String, Format>, Registry) {
        // (carrier, type) → (methods declaring it, whats), in the registry's order.
        let mut found: Vec<((&str, TypeId), (Vec<&str>, Vec<&str>), Entry)> = Vec::new();
        for method in super::super::registry::built_in() {
            let mut declared = Payloads::default();
            (method.payloads)(&mut declared);
            for e in declared.entries {
                let at = found
                    .iter()
                    .position(|((c, t), _, _)| (*c, *t) == (e.carrier, e.ty));
                let i = at.unwrap_or_else(|| {
                    found.push(((e.carrier, e.ty), (Vec::new(), Vec::new()), e));
                    found.len() - 1
                });
                let (methods, whats) = &mut found[i].1;
                if !methods.contains(&method.name) {
                    methods.push(method.name);
                }
                if !whats.contains(&e.what) {
                    whats.push(e.what);
                }
            }
        }
        let mut tracer = Tracer::new(TracerConfig::default());
        let mut payloads = BTreeMap::new();
        for ((carrier, _), (methods, whats), e) in &found {
            let by = match *carrier {
                super::OWN => methods.join(", "),
                pass => pass.to_string(),
            };
            let name = format!("{by}: {}", whats.join(", "));
            let format =
                (e.trace)(&mut tracer).unwrap_or_else(|err| panic!("tracing {name}: {err}"));
            payloads.insert(name, format);
        }
        // Checkpoints lead with the step's number.
        let (format, _) = tracer.trace_simple_type::<u32>().expect("a u32 traces");
        payloads.insert("checkpoint: step".into(), format);
        let registry = tracer
            .registry()
            .unwrap_or_else(|e| panic!("an incomplete layout: {e}"));
        (payloads, registry)
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
            std::fs::write(&path, json + "\n")
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
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
            // Payloads pinned and no longer declared.
            .chain(
                pinned
                    .payloads
                    .keys()
                    .filter(|name| !payloads.contains_key(*name)),
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
}
