//! What a file may make us allocate. A header states sizes (an image's width and height, a
//! PLY element's count) before the bytes that fill them; a stated size is checked against
//! these limits, and against the bytes the file actually has, before anything is allocated
//! for it, so a small file cannot claim gigabytes.

/// Most pixels of one image a scene may use (an environment map, a texture, a reference):
/// 2²⁷, a 16384 × 8192 environment map. As float RGB that is 1.5 GiB.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 27;

/// Most bytes one image's channels may take decoded, all of them: 4 GiB, a 16384 × 8192
/// image in eight float channels. An OpenEXR decoder unpacks every channel of a block,
/// whether it is read or not, so a header listing thousands of channels over a large data
/// window claims that much memory.
pub const MAX_IMAGE_BYTES: u64 = 1 << 32;

/// Checks the bytes an image's `channels` channels of `bytes_per_pixel` bytes a pixel in all
/// take decoded, at `width`×`height`, against [`MAX_IMAGE_BYTES`].
pub fn check_image_bytes(
    width: u64,
    height: u64,
    channels: usize,
    bytes_per_pixel: u64,
) -> Result<(), String> {
    let bytes = width.saturating_mul(height).saturating_mul(bytes_per_pixel);
    if bytes > MAX_IMAGE_BYTES {
        return Err(format!(
            "its header claims {width}×{height} pixels in {channels} channels of {bytes_per_pixel} bytes a pixel in all ({bytes} bytes decoded), over the limit of {MAX_IMAGE_BYTES} bytes an image"
        ));
    }
    Ok(())
}

/// Checks an image's stated size: at least one pixel, at most [`MAX_IMAGE_PIXELS`].
/// The error says what the header claims and the limit; the caller names the file.
pub fn check_image_size(width: u64, height: u64) -> Result<(), String> {
    let pixels = width.saturating_mul(height);
    if pixels == 0 {
        return Err(format!(
            "its header claims {width}×{height} pixels: expected an image of at least 1×1"
        ));
    }
    if pixels > MAX_IMAGE_PIXELS {
        return Err(format!(
            "its header claims {width}×{height} pixels ({pixels}), over the limit of {MAX_IMAGE_PIXELS} pixels an image (16384×8192)"
        ));
    }
    Ok(())
}

/// Checks that `count` elements of at least `min_bytes` each fit in the `available` bytes a
/// file has left: what a stated count may claim.
pub fn check_count(what: &str, count: u64, min_bytes: u64, available: u64) -> Result<(), String> {
    if count.saturating_mul(min_bytes.max(1)) > available {
        return Err(format!(
            "its header claims {count} {what} of at least {} bytes each, but the file has only {available} bytes after its header",
            min_bytes.max(1)
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stated_sizes_over_the_limits_are_refused_with_the_claim() {
        assert!(check_image_size(16384, 8192).is_ok());
        let e = check_image_size(60000, 60000).unwrap_err();
        assert!(e.contains("60000×60000") && e.contains("134217728"), "{e}");
        assert!(check_image_size(0, 5).is_err());
        assert!(check_image_size(u64::MAX, u64::MAX).is_err());
        assert!(check_count("vertices", 10, 12, 120).is_ok());
        let e = check_count("vertices", 11, 12, 120).unwrap_err();
        assert!(e.contains("11 vertices") && e.contains("120 bytes"), "{e}");
        assert!(check_count("faces", u64::MAX, 0, 1 << 40).is_err());
        assert!(check_image_bytes(16384, 8192, 8, 32).is_ok());
        let e = check_image_bytes(16384, 8192, 9, 36).unwrap_err();
        assert!(e.contains("9 channels") && e.contains("4831838208"), "{e}");
        assert!(check_image_bytes(u64::MAX, u64::MAX, 1, u64::MAX).is_err());
    }
}
