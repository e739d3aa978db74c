//! What a glTF file must satisfy before the gltf crate reads it: the rules of glTF 2.0 that
//! the crate's validation does not check but its readers assume, and panic on when broken.

use gltf::json::Root;
use gltf::json::validation::Checked;

use super::GltfError;

/// Every rule below, in file order.
pub(super) fn check(root: &Root) -> Result<(), GltfError> {
    primitive_accessors(root)?;
    images(root)
}

/// Every accessor a mesh primitive's attributes name exists (gltf-json's validation reads the
/// POSITION accessor's bounds before checking that it does).
fn primitive_accessors(root: &Root) -> Result<(), GltfError> {
    let count = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, accessor) in &primitive.attributes {
                if accessor.value() >= count {
                    let name = match semantic {
                        Checked::Valid(s) => s.to_string(),
                        Checked::Invalid => "?".into(),
                    };
                    return Err(GltfError::new(
                        format!("meshes[{m}].primitives[{p}].attributes.{name}"),
                        format!(
                            "accessor {} does not exist: expected an index below {count}, the file's accessors",
                            accessor.value()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Every image names its data: a buffer view with its MIME type, or a URI.
fn images(root: &Root) -> Result<(), GltfError> {
    for (i, image) in root.images.iter().enumerate() {
        let at = format!("images[{i}]");
        match (&image.buffer_view, &image.mime_type, &image.uri) {
            (Some(_), None, _) => {
                return Err(GltfError::new(
                    format!("{at}.mimeType"),
                    "expected a MIME type (image/png or image/jpeg) for an image in a buffer view",
                ));
            }
            (None, _, None) => {
                return Err(GltfError::new(
                    at,
                    "expected a uri or a bufferView: the image has no data",
                ));
            }
            _ => {}
        }
    }
    Ok(())
}
