//! Buffers (the GLB chunk, base64 `data:` URIs or files beside the glTF) and the accessors
//! of a primitive, each checked against the bytes it reads before it is read.

use std::path::Path;

use base64::Engine;
use glam::Vec3;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::{GltfError, named};
use crate::source::{SceneSource, confine};

/// Every buffer's bytes, by index.
pub(super) fn load(
    doc: &gltf::Document,
    blob: Option<&[u8]>,
    source: &dyn SceneSource,
    dir: &Path,
) -> Result<Vec<Vec<u8>>, GltfError> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let at = named("buffers", buffer.index(), buffer.name());
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => blob
                .ok_or_else(|| {
                    GltfError::new(
                        &at,
                        "refers to the GLB binary chunk, which the file does not have",
                    )
                })?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) => uri_bytes(uri, source, dir, &at)?,
        };
        if bytes.len() < buffer.length() {
            return Err(GltfError::new(
                at,
                format!(
                    "holds {} bytes; expected byteLength {}",
                    bytes.len(),
                    buffer.length()
                ),
            ));
        }
        out.push(bytes);
    }
    Ok(out)
}

/// The bytes a URI names: a base64 `data:` URI, or a file relative to the glTF (which may not
/// leave the scene's folder).
fn uri_bytes(
    uri: &str,
    source: &dyn SceneSource,
    dir: &Path,
    at: &str,
) -> Result<Vec<u8>, GltfError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((_, payload)) = rest.split_once(";base64,") else {
            return Err(GltfError::new(
                at,
                "expected a base64 data URI (data:…;base64,…)",
            ));
        };
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| GltfError::new(at, format!("the data URI is not valid base64: {e}")));
    }
    if uri.contains("://") {
        return Err(GltfError::new(
            at,
            format!("refers to {uri}; expected a file beside the glTF or a data URI"),
        ));
    }
    let decoded = urlencoding::decode(uri).map_err(|e| {
        GltfError::new(
            at,
            format!("the URI {uri} is not valid UTF-8 once decoded: {e}"),
        )
    })?;
    let rel = confine(&dir.join(decoded.as_ref()).to_string_lossy())
        .map_err(|m| GltfError::new(at, format!("uri \"{uri}\": {m}")))?;
    source.read(&rel).map_err(|e| {
        GltfError::new(
            at,
            format!("cannot read {}: {e}", source.display_path(&rel).display()),
        )
    })
}

/// The bytes of an image: a buffer view (as in a .glb) or a URI.
pub(super) fn image_bytes(
    image: &gltf::Image,
    data: &[Vec<u8>],
    source: &dyn SceneSource,
    dir: &Path,
    at: &str,
) -> Result<Vec<u8>, GltfError> {
    match image.source() {
        gltf::image::Source::Uri { uri, .. } => uri_bytes(uri, source, dir, at),
        gltf::image::Source::View { view, .. } => {
            let buffer = view.buffer().index();
            let (start, end) = (view.offset(), view.offset() + view.length());
            data.get(buffer)
                .and_then(|b| b.get(start..end))
                .map(<[u8]>::to_vec)
                .ok_or_else(|| {
                    GltfError::new(
                        at,
                        format!("bufferView {} lies outside buffer {buffer}", view.index()),
                    )
                })
        }
    }
}

/// Checks that `accessor` lies within its buffer view and buffer, and has the type expected.
fn check(
    accessor: &gltf::Accessor,
    data: &[Vec<u8>],
    what: &str,
    types: &[DataType],
    dims: Dimensions,
    at: &str,
) -> Result<(), GltfError> {
    let here = format!(
        "{at} {what} ({})",
        named("accessors", accessor.index(), accessor.name())
    );
    if accessor.sparse().is_some() {
        return Err(GltfError::new(here, "sparse accessors are not supported"));
    }
    if !types.contains(&accessor.data_type()) || accessor.dimensions() != dims {
        return Err(GltfError::new(
            here,
            format!(
                "expected {dims:?} of {types:?}, got {:?} of {:?}",
                accessor.dimensions(),
                accessor.data_type()
            ),
        ));
    }
    let Some(view) = accessor.view() else {
        return Err(GltfError::new(
            here,
            "has no bufferView (all zeros): expected data",
        ));
    };
    let elem = accessor.size();
    let stride = view.stride().unwrap_or(elem);
    let count = accessor.count();
    // glTF 2.0 requires count ≥ 1; the gltf crate's readers compute count − 1 unchecked.
    if count == 0 {
        return Err(GltfError::new(here, "has 0 elements: expected at least 1"));
    }
    // offset + stride·(count − 1) + size, in sums that cannot wrap.
    let need = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(elem))
        .and_then(|n| n.checked_add(accessor.offset()));
    if need.is_none_or(|need| need > view.length()) {
        let need = need.map_or("more than 2^64".to_string(), |n| n.to_string());
        return Err(GltfError::new(
            here,
            format!(
                "{count} elements from byte {} need {need} bytes of bufferView {}, which has {}",
                accessor.offset(),
                view.index(),
                view.length()
            ),
        ));
    }
    let buffer = view.buffer().index();
    let have = data.get(buffer).map_or(0, Vec::len);
    let end = view.offset().checked_add(view.length());
    if end.is_none_or(|end| end > have) {
        let end = end.map_or("past 2^64".to_string(), |n| n.to_string());
        return Err(GltfError::new(
            here,
            format!(
                "bufferView {} ends at byte {end} of buffer {buffer}, which has {have}",
                view.index(),
            ),
        ));
    }
    Ok(())
}

/// The primitive's triangles (`None`, with a warning, for points and lines).
pub(super) fn triangles(
    prim: &gltf::Primitive,
    data: &[Vec<u8>],
    at: &str,
    warnings: &mut Vec<String>,
) -> Result<Option<Vec<[u32; 3]>>, GltfError> {
    let mode = prim.mode();
    if matches!(
        mode,
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
    ) {
        warnings.push(format!("{at}: {mode:?} are not surfaces: skipped"));
        return Ok(None);
    }
    let reader = prim.reader(|b| data.get(b.index()).map(Vec::as_slice));
    let indices: Vec<u32> = match prim.indices() {
        Some(acc) => {
            check(
                &acc,
                data,
                "indices",
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
                at,
            )?;
            let Some(read) = reader.read_indices() else {
                return Err(GltfError::new(at, "cannot read the indices"));
            };
            read.into_u32().collect()
        }
        None => {
            let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
                return Err(GltfError::new(at, "has no POSITION attribute"));
            };
            (0..pos.count() as u32).collect()
        }
    };
    let tris = match mode {
        Mode::Triangles => {
            if !indices.len().is_multiple_of(3) {
                return Err(GltfError::new(
                    at,
                    format!(
                        "{} indices: expected a multiple of 3 for triangles",
                        indices.len()
                    ),
                ));
            }
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
        // Every other strip triangle is wound the other way.
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                let (a, b, c) = (indices[i - 2], indices[i - 1], indices[i]);
                if i % 2 == 0 { [a, b, c] } else { [b, a, c] }
            })
            .collect(),
        Mode::TriangleFan => (2..indices.len())
            .map(|i| [indices[i - 1], indices[i], indices[0]])
            .collect(),
        _ => unreachable!("points and lines returned above"),
    };
    Ok(Some(tris))
}

/// TEXCOORD_`set` (float, or normalised unsigned bytes or shorts), if present: one per
/// vertex.
pub(super) fn uvs(
    prim: &gltf::Primitive,
    data: &[Vec<u8>],
    set: u32,
    vertices: usize,
    at: &str,
) -> Result<Option<Vec<glam::Vec2>>, GltfError> {
    let Some(acc) = prim.get(&gltf::Semantic::TexCoords(set)) else {
        return Ok(None);
    };
    let name = format!("TEXCOORD_{set}");
    check(
        &acc,
        data,
        &name,
        &[DataType::F32, DataType::U8, DataType::U16],
        Dimensions::Vec2,
        at,
    )?;
    let reader = prim.reader(|b| data.get(b.index()).map(Vec::as_slice));
    let uvs: Vec<glam::Vec2> = reader
        .read_tex_coords(set)
        .ok_or_else(|| GltfError::new(at, format!("cannot read {name}")))?
        .into_f32()
        .map(glam::Vec2::from)
        .collect();
    if uvs.len() != vertices {
        return Err(GltfError::new(
            at,
            format!(
                "{} {name} values for {vertices} positions: expected one each",
                uvs.len()
            ),
        ));
    }
    if let Some(i) = uvs.iter().position(|t| !t.is_finite()) {
        return Err(GltfError::new(at, format!("{name} {i} is not finite")));
    }
    Ok(Some(uvs))
}

/// TANGENT (float xyzw, w the bitangent's sign), if present: one per vertex.
pub(super) fn tangents(
    prim: &gltf::Primitive,
    data: &[Vec<u8>],
    vertices: usize,
    at: &str,
) -> Result<Option<Vec<glam::Vec4>>, GltfError> {
    let Some(acc) = prim.get(&gltf::Semantic::Tangents) else {
        return Ok(None);
    };
    check(
        &acc,
        data,
        "TANGENT",
        &[DataType::F32],
        Dimensions::Vec4,
        at,
    )?;
    let reader = prim.reader(|b| data.get(b.index()).map(Vec::as_slice));
    let t: Vec<glam::Vec4> = reader
        .read_tangents()
        .ok_or_else(|| GltfError::new(at, "cannot read TANGENT"))?
        .map(glam::Vec4::from)
        .collect();
    if t.len() != vertices || t.iter().any(|v| !v.is_finite()) {
        return Err(GltfError::new(
            at,
            format!(
                "{} TANGENT values for {vertices} positions: expected one finite value each",
                t.len()
            ),
        ));
    }
    Ok(Some(t))
}

/// Positions and (if present) normals, every value finite.
pub(super) fn attributes(
    prim: &gltf::Primitive,
    data: &[Vec<u8>],
    at: &str,
    warnings: &mut Vec<String>,
) -> Result<(Vec<Vec3>, Option<Vec<Vec3>>), GltfError> {
    let reader = prim.reader(|b| data.get(b.index()).map(Vec::as_slice));
    let Some(acc) = prim.get(&gltf::Semantic::Positions) else {
        return Err(GltfError::new(at, "has no POSITION attribute"));
    };
    check(
        &acc,
        data,
        "POSITION",
        &[DataType::F32],
        Dimensions::Vec3,
        at,
    )?;
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| GltfError::new(at, "cannot read POSITION"))?
        .map(Vec3::from)
        .collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(GltfError::new(
            at,
            format!(
                "POSITION {i} is {}: expected finite coordinates",
                positions[i]
            ),
        ));
    }
    let normals = match prim.get(&gltf::Semantic::Normals) {
        None => None,
        Some(acc) => {
            check(&acc, data, "NORMAL", &[DataType::F32], Dimensions::Vec3, at)?;
            let ns: Vec<Vec3> = reader
                .read_normals()
                .ok_or_else(|| GltfError::new(at, "cannot read NORMAL"))?
                .map(Vec3::from)
                .collect();
            if ns.len() != positions.len() {
                return Err(GltfError::new(
                    at,
                    format!(
                        "{} normals for {} positions: expected one each",
                        ns.len(),
                        positions.len()
                    ),
                ));
            }
            // A zero or non-finite normal gives no shading frame: shade by the faces instead.
            let bad = ns
                .iter()
                .filter(|n| !(n.is_finite() && n.length_squared() > 0.0))
                .count();
            if bad > 0 {
                warnings.push(format!(
                    "{at}: {bad} NORMAL values are zero or not finite: shaded by face normals"
                ));
                None
            } else {
                Some(ns)
            }
        }
    };
    Ok((positions, normals))
}
