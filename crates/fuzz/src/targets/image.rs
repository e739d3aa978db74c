//! `image`: an image as the scene loader decodes it: OpenEXR (by its magic number) as an
//! environment map, anything else as a colour and as a data texture (PNG or JPEG, by content).

use tessera_scene::texture::{TextureRole, decode};

use super::find;
use crate::{Target, fixtures, repo};

pub const TARGET: Target = Target {
    name: "image",
    about: "OpenEXR, PNG, JPEG: decoded as an environment map or a texture",
    run,
    seeds,
};

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

fn run(data: &[u8]) -> bool {
    match data.starts_with(&EXR_MAGIC) {
        true => tessera_scene::image::read_exr_rgb(data).is_ok(),
        false => {
            let color = decode(data, "fuzz", TextureRole::Color).is_ok();
            decode(data, "fuzz", TextureRole::Data).is_ok() && color
        }
    }
}

/// Small images of each format, and the repository's PNGs and small EXRs.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let mut out = vec![
        ("small.png".to_string(), fixtures::png(8, 8)),
        ("small.jpg".to_string(), fixtures::jpeg(8, 8)),
        ("small.exr".to_string(), fixtures::exr(16, 8)),
    ];
    out.extend(
        find(&repo().join("scenes"), &[".png", "-32.exr"])
            .into_iter()
            .filter(|(_, b)| b.len() < 64 << 10),
    );
    out
}
