//! `tessera-fuzz`: the fuzz targets' command line.
//!
//! - `tessera-fuzz list`: the targets.
//! - `tessera-fuzz seeds DIR`: each target's starting inputs, as `DIR/NAME/*`, those of at
//!   most [`MAX_SEED_BYTES`].
//! - `tessera-fuzz replay NAME FILE...`: feeds files to a target here (a crash to reproduce).
//! - `tessera-fuzz afl NAME`: the target under AFL++ (built with `cargo afl build --features
//!   afl`; `scripts/fuzz` runs it).

use std::path::PathBuf;

use anyhow::{Context, bail};

/// The largest seed AFL++ starts from. It mutates and trims byte by byte, so one large seed
/// slows every later execution of the queue it grows; the suite still replays the larger
/// ones (`tests/regressions.rs`).
const MAX_SEED_BYTES: usize = 64 << 10;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let target = |name: &str| {
        tessera_fuzz::lookup(name).with_context(|| {
            let names: Vec<&str> = tessera_fuzz::TARGETS.iter().map(|t| t.name).collect();
            format!(
                "no fuzz target {name:?}: expected one of {}",
                names.join(", ")
            )
        })
    };
    match args
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>()
        .as_slice()
    {
        ["list"] => {
            for t in tessera_fuzz::TARGETS {
                println!("{:8} {}", t.name, t.about);
            }
        }
        ["seeds", dir] => {
            for t in tessera_fuzz::TARGETS {
                let folder = PathBuf::from(dir).join(t.name);
                std::fs::create_dir_all(&folder)
                    .with_context(|| format!("cannot create {}", folder.display()))?;
                let seeds: Vec<_> = (t.seeds)()
                    .into_iter()
                    .filter(|(_, bytes)| bytes.len() <= MAX_SEED_BYTES)
                    .collect();
                for (name, bytes) in &seeds {
                    std::fs::write(folder.join(name), bytes)
                        .with_context(|| format!("cannot write {}/{name}", folder.display()))?;
                }
                println!("{}: {} seeds", t.name, seeds.len());
            }
        }
        ["replay", name, files @ ..] => {
            let t = target(name)?;
            for f in files.iter() {
                let bytes = std::fs::read(f).with_context(|| format!("cannot read {f}"))?;
                let accepted = (t.run)(&bytes);
                println!("{f}: {}", if accepted { "accepted" } else { "refused" });
            }
        }
        ["afl", name] => afl(target(name)?)?,
        _ => bail!("usage: tessera-fuzz list | seeds DIR | replay TARGET FILE... | afl TARGET"),
    }
    Ok(())
}

#[cfg(feature = "afl")]
fn afl(t: &'static tessera_fuzz::Target) -> anyhow::Result<()> {
    afl::fuzz!(|data: &[u8]| {
        (t.run)(data);
    });
    Ok(())
}

#[cfg(not(feature = "afl"))]
fn afl(_: &'static tessera_fuzz::Target) -> anyhow::Result<()> {
    bail!(
        "this build has no AFL++ driver: build it with `cargo afl build --features afl` (scripts/fuzz)"
    )
}
