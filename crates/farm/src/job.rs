//! A job as the farm holds it: compiled by the core ([`tessera_render::job`], whose settings,
//! frames and limits the farm's API carries), loaded from its bundle, and its tasks' results
//! checked before they are kept.

use std::io::Read;

use tessera_render::method::Plan;

use crate::bundle::Bundle;

pub use tessera_render::job::{
    Choose, Compiled, FRAMES_IN_MEMORY, FrameRange, Limits, Options, RenderSettings, compile,
    decisions, default_max_memory, frame_file_name, job_memory, machine_memory, write_frame,
};
pub use tessera_render::method::{MAX_TILE, TaskSpec};

/// Compiles a job of the scene file `scene` in the bundle whose bytes are `tar`: the bundle
/// read, the scene loaded from it, the job compiled ([`compile`]). Every process that holds a
/// job (the coordinator when it is submitted and when it plans it again, each worker) starts
/// here. Errors name the file and the field.
pub fn compile_bundled(
    tar: &[u8],
    scene: &str,
    settings: &RenderSettings,
    frames: Option<FrameRange>,
    options: Options,
) -> Result<Compiled, String> {
    let desc = Bundle::from_tar(tar)?
        .load(scene)
        .map_err(|e| e.to_string())?;
    let frames = frames.unwrap_or(FrameRange {
        first: 1,
        last: desc.frame_count(),
    });
    compile(desc, settings, frames, options).map_err(|e| format!("{scene}: {e}"))
}

/// Checks a task's result stream before it is kept: a whole wire stream of the task's step
/// schema, naming `spec`, whose value fits the task (its tile's size, its pass's shape) and
/// after which nothing follows. Returns the payload's length in bytes.
pub fn check_result(plan: &dyn Plan, spec: &TaskSpec, stream: impl Read) -> anyhow::Result<u64> {
    let passes = plan.passes();
    let pass = match spec.is_pass() {
        true => Some(
            *passes
                .get(spec.step as usize)
                .ok_or_else(|| anyhow::anyhow!("the job has no pass {}", spec.step))?,
        ),
        false => None,
    };
    let schema = pass.map_or_else(|| plan.schema(), |p| p.schema());
    let (mut reader, header) = tessera_render::wire::Reader::new(stream)?;
    if header.what != "result" || header.schema != schema {
        anyhow::bail!(
            "expected a result of schema {schema}, got a {} of schema {}",
            header.what,
            header.schema
        );
    }
    if header.task.as_ref() != Some(spec) {
        anyhow::bail!(
            "the result names task {:?}, the lease is for {spec:?}",
            header.task
        );
    }
    let value = match pass {
        Some(p) => p.decode(&mut reader),
        None => plan.decode(&mut reader),
    }?;
    plan.fits(spec, value.as_ref())
        .map_err(|e| anyhow::anyhow!("does not fit its task: {e}"))?;
    let payload = reader.payload_len();
    let mut rest = reader.finish()?;
    if rest.read(&mut [0u8; 1])? != 0 {
        anyhow::bail!("bytes follow the end of the result's wire stream");
    }
    Ok(payload)
}
