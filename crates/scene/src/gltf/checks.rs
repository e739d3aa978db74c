//! What a glTF file must satisfy before the gltf crate reads it: the rules of glTF 2.0 that
//! the crate's validation does not check but its readers assume, and panic on when broken.

use gltf::json::validation::Checked;
use gltf::json::{Index, Root, buffer};

use super::GltfError;

/// Every rule below, in file order.
pub(super) fn check(root: &Root) -> Result<(), GltfError> {
    primitive_accessors(root)?;
    strides(root)?;
    images(root)
}

/// A GLB's header states a length no shorter than the header itself (the gltf crate
/// subtracts the header's 12 bytes from it unchecked). Bytes that are not a GLB pass.
pub(super) fn glb_header(bytes: &[u8]) -> Result<(), GltfError> {
    const HEADER: u32 = 12;
    if let Some(length) = bytes
        .strip_prefix(b"glTF")
        .and_then(|rest| rest.get(4..8))
        .map(|l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]))
        && length < HEADER
    {
        return Err(GltfError::new(
            "GLB header",
            format!(
                "the file's length is given as {length} bytes: expected at least the header's {HEADER}"
            ),
        ));
    }
    Ok(())
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

/// A buffer view's `byteStride`, where given, is at least the size of each element read
/// through it (glTF 2.0 §3.6.2.4; the gltf crate's readers assert it): an accessor's element,
/// a sparse accessor's indices and values.
fn strides(root: &Root) -> Result<(), GltfError> {
    let check = |view: Index<buffer::View>, element: usize, at: &str| {
        let Some(stride) = root
            .buffer_views
            .get(view.value())
            .and_then(|v| v.byte_stride)
        else {
            return Ok(());
        };
        if stride.0 < element {
            return Err(GltfError::new(
                format!("bufferViews[{}].byteStride", view.value()),
                format!(
                    "{} bytes between elements, but {at} reads elements of {element} bytes through it: expected a stride of at least {element}",
                    stride.0
                ),
            ));
        }
        Ok(())
    };
    for (i, a) in root.accessors.iter().enumerate() {
        let (Checked::Valid(component), Checked::Valid(kind)) = (&a.component_type, &a.type_)
        else {
            continue;
        };
        let element = component.0.size() * kind.multiplicity();
        let at = format!("accessors[{i}]");
        if let Some(view) = a.buffer_view {
            check(view, element, &at)?;
        }
        if let Some(sparse) = &a.sparse {
            if let Checked::Valid(indices) = &sparse.indices.component_type {
                check(
                    sparse.indices.buffer_view,
                    indices.0.size(),
                    &format!("{at}.sparse.indices"),
                )?;
            }
            check(
                sparse.values.buffer_view,
                element,
                &format!("{at}.sparse.values"),
            )?;
        }
    }
    Ok(())
}
