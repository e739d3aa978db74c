//! A job as the farm holds it: compiled by the core ([`tessera_render::job`], whose settings,
//! frames and limits the farm's API carries), loaded from its bundle, and its tasks' results
//! checked before they are kept.
//!
//! A job that asks for `auto` and carries no choice is queued with one task, its **pilot**
//! ([`pilot_task`]): the worker that leases it measures `auto`'s candidates on the job's first
//! frame ([`Choose::Measure`]) and returns the choice ([`write_choice`]); the coordinator
//! keeps it with the job's settings and only then plans the job's passes and frames. The
//! measurement, seconds to minutes of rendering, runs on a worker, not in the request that
//! submitted the job.

use std::io::{Read, Write};

use tessera_render::method::Plan;
use tessera_render::method::auto::Choice;
use tessera_render::wire::{self, Header};

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

/// The step of a job's pilot task: frame 0 (no frame's), after every pass.
pub const PILOT_STEP: u32 = u32::MAX;

/// The schema of a pilot's result: `auto`'s choice as JSON (its optional fields are left out
/// when unset, which the wire's positional encoding cannot express).
const CHOICE_SCHEMA: &str = "auto-choice/1";

/// The largest choice a pilot's result may hold (a report of a few lines per candidate).
const MAX_CHOICE_BYTES: u64 = 1 << 20;

/// The task that measures `auto` for a job that awaits its choice.
pub fn pilot_task() -> TaskSpec {
    TaskSpec::new("pilot", 0, PILOT_STEP, 0)
}

/// Whether `spec` is a job's pilot ([`pilot_task`]).
pub fn is_pilot(spec: &TaskSpec) -> bool {
    is_pilot_step(spec.frame, spec.step)
}

/// Whether step `step` of frame `frame` (0: the job's passes) is a job's pilot.
pub fn is_pilot_step(frame: u32, step: u32) -> bool {
    frame == 0 && step == PILOT_STEP
}

/// Writes the result of pilot task `spec`: `choice`, as a wire stream.
pub fn write_choice(out: impl Write, spec: &TaskSpec, choice: &Choice) -> anyhow::Result<()> {
    let mut header = Header::new("result", CHOICE_SCHEMA);
    header.task = Some(spec.clone());
    let mut w = wire::Writer::new(out, &header)?;
    serde_json::to_writer(&mut w, choice)?;
    w.finish()?;
    Ok(())
}

/// Reads the result of pilot task `spec`: a whole wire stream of the choice's schema, naming
/// `spec`, whose choice names a method `auto` may choose, and after which nothing follows.
/// Returns the choice and the payload's length in bytes.
pub fn read_choice(spec: &TaskSpec, stream: impl Read) -> anyhow::Result<(Choice, u64)> {
    read_result(spec, CHOICE_SCHEMA, stream, |reader| {
        let choice: Choice =
            serde_json::from_reader(reader.take(MAX_CHOICE_BYTES)).map_err(|e| {
                anyhow::anyhow!("auto's choice (JSON, at most {MAX_CHOICE_BYTES} bytes): {e}")
            })?;
        choice
            .check()
            .map_err(|e| anyhow::anyhow!("auto's choice: {e}"))?;
        Ok(choice)
    })
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
    let ((), payload) = read_result(spec, &schema, stream, |reader| {
        let value = match pass {
            Some(p) => p.decode(reader),
            None => plan.decode(reader),
        }?;
        plan.fits(spec, value.as_ref())
            .map_err(|e| anyhow::anyhow!("does not fit its task: {e}"))
    })?;
    Ok(payload)
}

/// Reads a result stream of task `spec`: its header says a result of `schema` naming `spec`,
/// `decode` reads the value, and the stream is whole with nothing after it. Returns the value
/// and the payload's length in bytes.
fn read_result<T>(
    spec: &TaskSpec,
    schema: &str,
    mut stream: impl Read,
    decode: impl FnOnce(&mut wire::Reader<&mut dyn Read>) -> anyhow::Result<T>,
) -> anyhow::Result<(T, u64)> {
    let (mut reader, header) = wire::Reader::new(&mut stream as &mut dyn Read)?;
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
    let value = decode(&mut reader)?;
    let payload = reader.payload_len();
    let rest = reader.finish()?;
    if rest.read(&mut [0u8; 1])? != 0 {
        anyhow::bail!("bytes follow the end of the result's wire stream");
    }
    Ok((value, payload))
}
