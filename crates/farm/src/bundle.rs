//! Scene bundles: a scene file and every file it references, as one tar archive that a client
//! uploads and workers download, addressed by the SHA-256 of its bytes.
//!
//! A bundle is packed deterministically (files sorted, no times or owners), so the same scene
//! always gives the same hash. Unpacking confines every entry to the bundle: absolute paths,
//! `..` that leaves it, links and devices are refused.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use sha2::{Digest, Sha256};
use tessera_scene::source::confine;
use tessera_scene::{DirSource, SceneDesc, SceneError, SceneSource};

/// The files of an unpacked bundle, by confined relative path.
#[derive(Debug, Clone, Default)]
pub struct Bundle {
    pub files: BTreeMap<PathBuf, Vec<u8>>,
}

impl SceneSource for Bundle {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        self.files.get(relative).cloned().ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such file in the uploaded scene bundle",
            )
        })
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        relative.to_path_buf()
    }
}

impl Bundle {
    /// Unpacks a tar archive, refusing entries that leave the bundle or are not plain files,
    /// entries whose bytes are fewer than their header claims, and an archive with no file.
    /// Nothing is allocated on a header's word: an entry's bytes are read as they come, so
    /// the archive's own length bounds what it can take.
    pub fn from_tar(bytes: &[u8]) -> Result<Bundle, String> {
        let mut archive = tar::Archive::new(bytes);
        let mut files = BTreeMap::new();
        let entries = archive
            .entries()
            .map_err(|e| format!("expected a tar archive: {e}"))?;
        for entry in entries {
            let mut entry = entry.map_err(|e| format!("expected a tar archive: {e}"))?;
            let raw = String::from_utf8_lossy(&entry.path_bytes()).into_owned();
            let kind = entry.header().entry_type();
            if kind.is_dir() {
                continue;
            }
            if !kind.is_file() {
                return Err(format!(
                    "bundle entry \"{raw}\": expected a regular file, got a {kind:?} entry"
                ));
            }
            let path = confine(&raw).map_err(|e| format!("bundle entry \"{raw}\": {e}"))?;
            let claimed = entry.size();
            if claimed > bytes.len() as u64 {
                return Err(format!(
                    "bundle entry \"{raw}\": its header claims {claimed} bytes, but the whole archive has {}",
                    bytes.len()
                ));
            }
            let mut data = Vec::new();
            std::io::Read::read_to_end(&mut entry, &mut data)
                .map_err(|e| format!("bundle entry \"{raw}\": {e}"))?;
            if data.len() as u64 != claimed {
                return Err(format!(
                    "bundle entry \"{raw}\": its header claims {claimed} bytes, the archive holds {} (cut short)",
                    data.len()
                ));
            }
            if files.insert(path, data).is_some() {
                return Err(format!(
                    "bundle entry \"{raw}\": expected each file once, this path comes twice"
                ));
            }
        }
        if files.is_empty() {
            return Err(
                "expected a tar archive of a scene file and the files it references, got no file"
                    .into(),
            );
        }
        Ok(Bundle { files })
    }

    /// Packs the files into a deterministic tar archive (GNU headers: paths of any length);
    /// a file that cannot be packed is an error naming it, never left out.
    pub fn to_tar(&self) -> Result<Vec<u8>, String> {
        let mut builder = tar::Builder::new(Vec::new());
        for (path, data) in &self.files {
            let mut header = tar::Header::new_gnu();
            header.set_size(data.len() as u64);
            header.set_mode(0o644);
            header.set_mtime(0);
            header.set_entry_type(tar::EntryType::Regular);
            builder
                .append_data(&mut header, path, data.as_slice())
                .map_err(|e| {
                    format!("cannot pack {} into the scene bundle: {e}", path.display())
                })?;
        }
        builder
            .into_inner()
            .map_err(|e| format!("cannot finish the scene bundle: {e}"))
    }

    /// Loads and validates the scene file `scene` of this bundle.
    pub fn load(&self, scene: &str) -> Result<SceneDesc, SceneError> {
        let name = confine(scene).map_err(|message| {
            SceneError::Invalid(vec![tessera_scene::Problem {
                file: PathBuf::from(scene),
                path: String::new(),
                message,
            }])
        })?;
        tessera_scene::load_from(self, &name)
    }

    /// Bundles the scene at `path` (a scene.json) with exactly the files it reads, after
    /// validating it as the coordinator will. Returns the bundle and the scene's file name.
    pub fn pack_scene(path: &Path) -> Result<(Bundle, SceneDesc, String), SceneError> {
        let (dir, name) = tessera_scene::source::scene_folder(path);
        let name = name.to_string_lossy().into_owned();
        let recording = Recording {
            inner: DirSource::new(dir),
            files: Mutex::new(BTreeMap::new()),
        };
        let desc = tessera_scene::load_from(&recording, Path::new(&name))?;
        let files = recording
            .files
            .into_inner()
            .unwrap_or_else(|e| e.into_inner());
        Ok((Bundle { files }, desc, name))
    }
}

/// A source that remembers every file read through it.
struct Recording {
    inner: DirSource,
    files: Mutex<BTreeMap<PathBuf, Vec<u8>>>,
}

impl SceneSource for Recording {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        let data = self.inner.read(relative)?;
        if let Ok(mut files) = self.files.lock() {
            files.insert(relative.to_path_buf(), data.clone());
        }
        Ok(data)
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        self.inner.display_path(relative)
    }
}

/// The content address of a bundle: SHA-256 of its bytes, in lower-case hex.
pub fn hash(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// SHA-256 of a file's bytes, in lower-case hex, read in chunks; and its length.
pub fn hash_file(path: &Path) -> std::io::Result<(String, u64)> {
    hash_reader(std::fs::File::open(path)?)
}

/// SHA-256 of what `file` reads to its end, in lower-case hex, read in chunks; and its length.
pub fn hash_reader(mut file: impl std::io::Read) -> std::io::Result<(String, u64)> {
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut len = 0u64;
    loop {
        let n = file.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        len += n as u64;
    }
    Ok((
        h.finalize().iter().map(|b| format!("{b:02x}")).collect(),
        len,
    ))
}

/// Whether `s` looks like a bundle hash (64 hex digits), so it is safe in a file name.
pub fn is_hash(s: &str) -> bool {
    s.len() == 64
        && s.bytes()
            .all(|b| b.is_ascii_hexdigit() && !b.is_ascii_uppercase())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packs_what_the_scene_reads_and_round_trips() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.json");
        let (bundle, desc, name) = Bundle::pack_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(name, "scene.json");
        assert!(bundle.files.contains_key(Path::new("scene.json")));
        assert!(
            bundle.files.len() > 1,
            "meshes are bundled: {:?}",
            bundle.files.keys()
        );
        assert!(!bundle.files.keys().any(|k| k.ends_with("reference.exr")));
        let tar = bundle.to_tar().expect("packs");
        assert_eq!(
            hash(&tar),
            hash(&bundle.to_tar().expect("packs")),
            "deterministic"
        );
        let back = Bundle::from_tar(&tar).expect("unpack");
        let again = back.load(&name).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(again.meshes.len(), desc.meshes.len());
    }

    #[test]
    fn long_paths_are_packed_and_a_missing_file_is_named() {
        let long = format!("{}/mesh.obj", "deep/".repeat(40));
        let bundle = Bundle {
            files: [(PathBuf::from(&long), b"v 0 0 0\n".to_vec())].into(),
        };
        let back = Bundle::from_tar(&bundle.to_tar().expect("packs")).expect("unpacks");
        assert!(
            back.files.contains_key(Path::new(&long)),
            "{:?}",
            back.files.keys()
        );
        // A scene naming a file its bundle lacks is refused with that file's name.
        let scene = r#"{ "units": "m", "camera": { "type": "pinhole", "position": [0, 0, -3], "look_at": [0, 0, 0], "fov_deg": 40 },
            "film": { "width": 8, "height": 8 }, "materials": { "m": { "type": "diffuse", "albedo": 0.5 } },
            "shapes": [ { "type": "mesh", "file": "gone.obj", "material": "m" } ] }"#;
        let bundle = Bundle {
            files: [(PathBuf::from("scene.json"), scene.as_bytes().to_vec())].into(),
        };
        let e = bundle.load("scene.json").unwrap_err().to_string();
        assert!(
            e.contains("gone.obj") && e.contains("shapes[0].file"),
            "{e}"
        );
    }

    #[test]
    fn refuses_entries_that_leave_the_bundle() {
        let mut builder = tar::Builder::new(Vec::new());
        let mut header = tar::Header::new_gnu();
        let data = b"v 0 0 0\n";
        header.set_size(data.len() as u64);
        header.set_entry_type(tar::EntryType::Regular);
        // Write the name into the header directly: the tar crate's setters refuse "..".
        let name = b"../../etc/evil.obj";
        header.as_old_mut().name[..name.len()].copy_from_slice(name);
        header.set_cksum();
        builder.append(&header, &data[..]).expect("append");
        let tar = builder.into_inner().expect("tar");
        let err = Bundle::from_tar(&tar).unwrap_err();
        assert!(err.contains("leaves"), "{err}");
        assert!(is_hash(&hash(b"x")) && !is_hash("../x"));
    }

    /// A tar of one entry named `name` whose header claims `claimed` bytes, followed by
    /// `body` (padded to a block) and the two zero blocks that end an archive.
    pub(crate) fn lying_tar(name: &str, claimed: u64, body: &[u8]) -> Vec<u8> {
        let mut header = tar::Header::new_gnu();
        header.set_path(name).expect("name");
        header.set_size(claimed);
        header.set_mode(0o644);
        header.set_entry_type(tar::EntryType::Regular);
        header.set_cksum();
        let mut tar = header.as_bytes().to_vec();
        tar.extend_from_slice(body);
        tar.resize(tar.len().next_multiple_of(512) + 1024, 0);
        tar
    }

    #[test]
    fn a_claimed_size_is_not_believed() {
        // 64 GiB claimed, 100 bytes there: refused without allocating the claim.
        let tar = lying_tar("scene.json", 64 << 30, &[b'x'; 100]);
        assert!(tar.len() <= 2048);
        let err = Bundle::from_tar(&tar).unwrap_err();
        assert!(
            err.contains("scene.json") && err.contains("68719476736"),
            "{err}"
        );
        // A claim within the archive's length, but past its end, is cut short.
        let tar = lying_tar("mesh.obj", 1600, &[b'v'; 100]);
        assert!(tar.len() > 1600);
        let err = Bundle::from_tar(&tar).unwrap_err();
        assert!(
            err.contains("mesh.obj") && err.contains("cut short"),
            "{err}"
        );
    }

    #[test]
    fn an_archive_without_files_is_refused() {
        for bytes in [Vec::new(), vec![0u8; 1024]] {
            let err = Bundle::from_tar(&bytes).unwrap_err();
            assert!(err.contains("got no file"), "{err}");
        }
    }
}
