//! Fuzz targets: each parser of untrusted input, called as the renderer, the coordinator or
//! a worker calls it. A target takes any bytes and must return: an error is fine, a panic,
//! an abort, a hang or an allocation a file merely claims is a defect.
//!
//! [`TARGETS`] is the one registry: `tessera-fuzz afl NAME` runs one under AFL++
//! (`scripts/fuzz` drives them all), `tessera-fuzz seeds DIR` writes each target's starting
//! inputs, and `tests/regressions.rs` replays every seed and every input that once failed
//! (`regressions/NAME/`) through the suite.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod fixtures;
pub mod targets;

pub use targets::TARGETS;

/// One fuzz target.
pub struct Target {
    /// Its name: a folder under `regressions/` and an argument of `tessera-fuzz`.
    pub name: &'static str,
    /// What it feeds and to what.
    pub about: &'static str,
    /// Feeds one input; never panics. True if the input was accepted all the way through
    /// (the seeds' tests check that the targets reach past their first check).
    pub run: fn(&[u8]) -> bool,
    /// Starting inputs, from the repository's own files and real renders: (file name, bytes).
    pub seeds: fn() -> Vec<(String, Vec<u8>)>,
}

/// The target called `name`.
pub fn lookup(name: &str) -> Option<&'static Target> {
    TARGETS.iter().find(|t| t.name == name)
}

/// The repository's root (scenes and regressions are read from it).
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The inputs that once made a target fail, kept as regressions: `regressions/NAME/*`.
pub fn regressions(name: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("regressions")
        .join(name);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut out: Vec<(String, Vec<u8>)> = entries
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_file())
        .map(|e| {
            let bytes = std::fs::read(e.path()).expect("a regression input is readable");
            (e.file_name().to_string_lossy().into_owned(), bytes)
        })
        .collect();
    out.sort();
    out
}

/// A scene folder in memory: the fixed files a target's input sits among.
#[derive(Default, Clone)]
pub struct Mem(pub BTreeMap<PathBuf, Vec<u8>>);

impl Mem {
    pub fn with(mut self, name: &str, bytes: Vec<u8>) -> Self {
        self.0.insert(PathBuf::from(name), bytes);
        self
    }
}

impl tessera_scene::SceneSource for Mem {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        self.0
            .get(relative)
            .cloned()
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "not in the folder"))
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        relative.to_path_buf()
    }
}

/// Loads `name` from `folder`, then does what `tessera render` does before the first ray:
/// plans the job (default settings, the farm's default limits) and builds the scene (BVH,
/// lights, textures).
pub fn load_plan_build(folder: &dyn tessera_scene::SceneSource, name: &str) -> bool {
    use tessera_render::job::{FrameRange, Limits, Options, RenderSettings, compile};
    let Ok(desc) = tessera_scene::load_from(folder, Path::new(name)) else {
        return false;
    };
    let limits = Limits::default();
    let settings = RenderSettings::default();
    let Ok(compiled) = compile(
        desc,
        &settings,
        FrameRange::single(1),
        Options::new(&limits),
    ) else {
        return false;
    };
    let _ = tessera_render::Scene::build(&compiled.job.desc);
    true
}

/// Every file of a folder of the repository (sorted by name), e.g. an example scene.
pub fn files_of(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.path().is_file())
                .filter_map(|e| {
                    let bytes = std::fs::read(e.path()).ok()?;
                    Some((e.file_name().to_string_lossy().into_owned(), bytes))
                })
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}
