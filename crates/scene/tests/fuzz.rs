//! The scene loader never panics, whatever it is given: ten thousand deterministic mutations of
//! the example scenes (bytes flipped, cut, duplicated; numbers replaced by extremes; keys and
//! types swapped) and of the mesh files they reference. Every input must give a scene or a
//! `SceneError` — never a panic.

use std::collections::BTreeMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use tessera_scene::SceneSource;

/// Files in memory: the scene and what it references.
struct Mem(BTreeMap<PathBuf, Vec<u8>>);

impl SceneSource for Mem {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        self.0
            .get(relative)
            .cloned()
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "not in memory"))
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        relative.to_path_buf()
    }
}

/// xorshift64*: a fixed, seedable stream.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const TOKENS: &[&str] = &[
    "NaN",
    "-1",
    "0",
    "-0",
    "1e39",
    "-1e39",
    "1e-45",
    "4294967296",
    "18446744073709551616",
    "\"\"",
    "\"../x.obj\"",
    "\"/etc/passwd\"",
    "null",
    "true",
    "[]",
    "{}",
    "[0,0]",
    "[1e30,1e30,1e30]",
    "\"box\"",
    "\"sphere\"",
    "\"mesh\"",
    "\"instance\"",
    "\"environment\"",
    "\"thin_lens\"",
    "{\"type\": \"nope\"}",
    "[[[[[[[[1]]]]]]]]",
    "\"\\u0000\"",
    "\"x\"",
];

fn mutate(rng: &mut Rng, data: &[u8]) -> Vec<u8> {
    let mut out = data.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(out.len() + 1);
        match rng.below(6) {
            0 => {
                if !out.is_empty() {
                    let i = rng.below(out.len());
                    out[i] = rng.next() as u8;
                }
            }
            1 => out.truncate(at),
            2 => {
                let end = (at + rng.below(64)).min(out.len());
                let piece = out[at..end].to_vec();
                out.splice(at..at, piece);
            }
            3 => {
                let end = (at + rng.below(16)).min(out.len());
                out.drain(at..end);
            }
            _ => {
                // Replace the number or word at `at` by a token.
                let is_word = |b: u8| b.is_ascii_alphanumeric() || b"-+.e\"_".contains(&b);
                let (mut s, mut e) = (at.min(out.len()), at.min(out.len()));
                while s > 0 && is_word(out[s - 1]) {
                    s -= 1;
                }
                while e < out.len() && is_word(out[e]) {
                    e += 1;
                }
                let t = TOKENS[rng.below(TOKENS.len())].as_bytes().to_vec();
                out.splice(s..e, t);
            }
        }
    }
    out
}

/// The example scenes with every file of their folders (images and meshes).
fn corpus() -> Vec<BTreeMap<PathBuf, Vec<u8>>> {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut out = Vec::new();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&scenes)
        .expect("scenes")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    dirs.extend(
        std::fs::read_dir(scenes.join("hard"))
            .expect("scenes/hard")
            .filter_map(|e| e.ok().map(|e| e.path())),
    );
    dirs.sort();
    for dir in dirs.iter().filter(|d| d.join("scene.json").exists()) {
        let mut files = BTreeMap::new();
        for e in std::fs::read_dir(dir).expect("dir").flatten() {
            let p = e.path();
            // Big reference images are not read by the loader; skip them.
            if p.is_file()
                && e.metadata().map_or(0, |m| m.len()) < 2_000_000
                && let (Some(name), Ok(data)) = (p.file_name(), std::fs::read(&p))
            {
                files.insert(PathBuf::from(name), data);
            }
        }
        out.push(files);
    }
    out
}

#[test]
fn the_loader_never_panics_on_mutated_scenes_and_meshes() {
    let corpus = corpus();
    assert!(corpus.len() >= 10, "{} scenes", corpus.len());
    let mut rng = Rng(0x7e55_e7a0_5eed_0001);
    let (mut ok, mut rejected) = (0, 0);
    for i in 0..10_000 {
        let mut files = corpus[i % corpus.len()].clone();
        // Mutate the scene file most of the time, otherwise one of its other files.
        let keys: Vec<PathBuf> = files.keys().cloned().collect();
        let target = if rng.below(3) > 0 {
            PathBuf::from("scene.json")
        } else {
            keys[rng.below(keys.len())].clone()
        };
        if let Some(data) = files.get(&target) {
            let mutated = mutate(&mut rng, data);
            files.insert(target.clone(), mutated);
        }
        let source = Mem(files);
        let result = catch_unwind(AssertUnwindSafe(|| {
            tessera_scene::load_from(&source, Path::new("scene.json"))
        }));
        match result {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(e)) => {
                assert!(!e.to_string().is_empty());
                rejected += 1;
            }
            Err(_) => {
                let bad = source.0.get(&target).cloned().unwrap_or_default();
                panic!(
                    "the loader panicked on case {i} (mutated {}):\n{}",
                    target.display(),
                    String::from_utf8_lossy(&bad[..bad.len().min(2000)])
                );
            }
        }
    }
    // Both outcomes happen: the mutations are neither all harmless nor all fatal.
    assert!(ok > 100 && rejected > 100, "ok {ok}, rejected {rejected}");
}
