//! Where scene files come from: a folder on disk today, an uploaded bundle on the farm.
//! Every path a scene names is relative to the scene's folder and may not leave it.

use std::path::{Component, Path, PathBuf};

/// Read access to the files of one scene, addressed by paths relative to the scene folder.
pub trait SceneSource {
    /// Reads a file given by a confined relative path (see [`confine`]).
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>>;
    /// How to show `relative` to a user (e.g. the full path on disk).
    fn display_path(&self, relative: &Path) -> PathBuf;
}

/// A scene folder on the local file system.
#[derive(Debug, Clone)]
pub struct DirSource {
    root: PathBuf,
}

impl DirSource {
    pub fn new(root: impl Into<PathBuf>) -> Self {
        DirSource { root: root.into() }
    }
}

impl SceneSource for DirSource {
    /// Reads a regular file whose resolved path (links followed) lies inside the folder: a
    /// link that leads out of it, or to a device or pipe, is refused.
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        use std::io::{Error, ErrorKind};
        let root = self.root.canonicalize()?;
        let path = self.root.join(relative).canonicalize()?;
        if !path.starts_with(&root) {
            return Err(Error::new(
                ErrorKind::PermissionDenied,
                format!(
                    "it resolves to {}, outside the scene folder {}: expected a file inside it",
                    path.display(),
                    root.display()
                ),
            ));
        }
        if !std::fs::metadata(&path)?.is_file() {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("{} is not a regular file", path.display()),
            ));
        }
        std::fs::read(path)
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        self.root.join(relative)
    }
}

/// The folder and file name of the scene file at `path`, its own link followed (the scene
/// file names its folder; the files it references must lie inside that folder). A path that
/// cannot be resolved is split as given, for the loader to report.
pub fn scene_folder(path: &Path) -> (PathBuf, PathBuf) {
    let real = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    let dir = real
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let name = real.file_name().map_or_else(|| real.clone(), PathBuf::from);
    (dir, name)
}

/// Normalises a path given in a scene file and checks that it stays inside the scene folder:
/// no absolute paths, no drive prefixes, no `..` that climbs above the folder.
/// Returns the normalised relative path, or what was expected.
pub fn confine(path: &str) -> Result<PathBuf, String> {
    if path.is_empty() {
        return Err(
            "expected a file path relative to the scene folder, got an empty string".into(),
        );
    }
    let mut out = PathBuf::new();
    for component in Path::new(path).components() {
        match component {
            Component::Normal(c) => out.push(c),
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return Err(format!(
                        "expected a path inside the scene folder, but \"{path}\" leaves it"
                    ));
                }
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(format!(
                    "expected a path relative to the scene folder, got the absolute path \"{path}\""
                ));
            }
        }
    }
    if out.as_os_str().is_empty() {
        return Err(format!(
            "expected a file path, \"{path}\" names the scene folder itself"
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn confine_accepts_relative_paths_and_normalises() {
        assert_eq!(
            confine("meshes/a.obj").unwrap(),
            PathBuf::from("meshes/a.obj")
        );
        assert_eq!(
            confine("./meshes/../a.obj").unwrap(),
            PathBuf::from("a.obj")
        );
    }

    #[test]
    fn confine_rejects_escapes_and_absolute_paths() {
        assert!(confine("../other/a.obj").unwrap_err().contains("leaves it"));
        assert!(
            confine("meshes/../../a.obj")
                .unwrap_err()
                .contains("leaves it")
        );
        assert!(confine("/etc/passwd").unwrap_err().contains("absolute"));
        assert!(confine("").is_err());
        assert!(confine("meshes/..").is_err());
    }

    #[cfg(unix)]
    #[test]
    fn a_link_out_of_the_folder_is_refused_and_one_inside_is_followed() {
        let outside = tempfile::tempdir().expect("dir");
        let secret = outside.path().join("secret.obj");
        std::fs::write(&secret, "v 0 0 0\n").expect("write");
        let scene = tempfile::tempdir().expect("dir");
        std::os::unix::fs::symlink(&secret, scene.path().join("leak.obj")).expect("link");
        std::fs::write(scene.path().join("mesh.obj"), "v 1 1 1\n").expect("write");
        std::os::unix::fs::symlink("mesh.obj", scene.path().join("alias.obj")).expect("link");
        let source = DirSource::new(scene.path());
        let e = source.read(Path::new("leak.obj")).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
        assert!(e.to_string().contains("outside the scene folder"), "{e}");
        assert_eq!(
            source.read(Path::new("alias.obj")).expect("inside"),
            b"v 1 1 1\n"
        );
        std::os::unix::fs::symlink("/dev/zero", scene.path().join("zero.obj")).expect("link");
        assert!(source.read(Path::new("zero.obj")).is_err());
        // The scene file's own link names its folder: the real one.
        let elsewhere = tempfile::tempdir().expect("dir");
        std::fs::write(scene.path().join("scene.json"), "{}").expect("write");
        let link = elsewhere.path().join("linked.json");
        std::os::unix::fs::symlink(scene.path().join("scene.json"), &link).expect("link");
        let (dir, name) = scene_folder(&link);
        assert_eq!(dir, scene.path().canonicalize().expect("real"));
        assert_eq!(name, Path::new("scene.json"));
    }
}
