//! What a method says about itself, for users and for the code that plans jobs.

use tessera_scene::SceneDesc;
use tessera_scene::setting::Setting;

use super::{Job, Payloads, Plan};
pub use crate::analysis::Transport;
use crate::integrator::Integrator;
use crate::scene::Scene;

/// A method as users meet it: its name (`integrator.type`, `--integrator`), what it does, and
/// the settings it reads; and what planning and `auto` need to know of it before it runs.
pub struct MethodInfo {
    pub name: &'static str,
    /// One line: what it is, after whom.
    pub summary: &'static str,
    /// What `spp` counts for it.
    pub spp: &'static str,
    /// Scene settings it reads besides `spp`, `max_depth`, `rr_depth` and `seed`, with the
    /// values each admits.
    pub settings: &'static [&'static Setting],
    /// Whether it renders translucent (subsurface) materials; a job of a scene that has them
    /// is refused for a method that does not, before it is planned.
    pub translucent: bool,
    /// What else of a scene it cannot render (a camera, a light), refused before it is
    /// planned and ruled out of `auto`'s candidates with the same words; `None`: nothing.
    pub refuses: Option<fn(&SceneDesc) -> Result<(), String>>,
    /// How much light transport it computes: whether scene analysis may choose it for a scene
    /// whose light it computes exactly without measuring anything.
    pub transport: Transport,
    /// How `auto` measures it; `None`: not one of `auto`'s candidates.
    pub pilot: Option<PilotInfo>,
    /// Its per-ray estimator with its passes run in-process, for tools and tests that render
    /// pixels directly ([`super::for_scene`]); `None` where its samples are not one ray's.
    pub per_ray: Option<PerRay>,
    /// Declares the payload types its plans write to the wire (its frame method's, its steps'
    /// inputs', its passes'), whose layouts a test pins to the wire version
    /// ([`super::Payloads`]).
    pub payloads: fn(&mut Payloads),
    /// Plans a job (the scene with the job's settings applied); errors name the setting and
    /// what was expected. Called through [`super::plan_as`], which refuses first what the
    /// method cannot render.
    pub plan: fn(&Job) -> Result<Box<dyn Plan>, String>,
}

impl MethodInfo {
    /// Whether it reads `setting`.
    pub fn reads(&self, setting: &Setting) -> bool {
        self.settings.iter().any(|s| std::ptr::eq(*s, setting))
    }
}

/// How a method's error falls with its samples n, for `auto`'s predictions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// v / n.
    Unbiased,
    /// v / n + b: b is kernel bias and the noise of a view-independent pass.
    Biased,
    /// v / n + b s(n) / s̄: progressive photon mapping, whose noise falls as a mean's while
    /// its radii still hold photons from many iterations, and whose kernel bias falls with the
    /// mean squared radius s(n) (step 2 of `auto::pilot`'s comment).
    Progressive,
}

/// Which light paths a method's samples find only rarely, so that a pilot of a few samples
/// does not see them and measures a variance smaller than its render's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sight {
    /// Finds every path from the camera's side and the lights' (light tracing, merging,
    /// photon maps, mutations).
    All,
    /// Traces from the camera only: caustics of a concentrated light are found only by
    /// hitting the light through the specular chain, and light seen through glass is as
    /// rare. Its pilot judges the others only where no candidate sees more.
    CameraOnly,
    /// Joins camera and light subpaths by connections, none of which can join a
    /// specular–diffuse–specular path: caustics of a concentrated light seen in a specular
    /// surface are found only by hitting the light.
    NoSpecularJoin,
}

/// What `auto`'s pilot needs of a candidate method.
#[derive(Debug, Clone, Copy)]
pub struct PilotInfo {
    /// Candidates are measured in increasing `order` (the cheap ones without passes first:
    /// they make the consensus that judges the biased ones).
    pub order: u32,
    pub model: Model,
    /// Samples per pixel of each of the pilot's two halves.
    pub k: u32,
    pub sight: Sight,
    /// Whether it traces one view-independent photon map of `photon_map.photons` photons:
    /// where the scene leaves the count, the pilot measures a map of a few photons first
    /// and the default count only where those cannot reach the goal.
    pub photon_map: bool,
    /// For a method whose frame costs much whatever its pixels and samples (a Metropolis
    /// bootstrap): the wall seconds its pilot's two frames would take, timed on a small part
    /// of one, so that a pilot that would cost more than is left stops before it starts.
    pub probe: Option<Probe>,
}

/// A method's per-ray estimator for frame 1 of `desc`, its passes run on `scene`, and what
/// was decided on the way.
pub type PerRay = fn(desc: &SceneDesc, scene: &Scene) -> (Box<dyn Integrator>, Vec<String>);

/// Wall seconds of a pilot's two frames of `desc` at frame `frame`, `k` samples per pixel
/// each, estimated from a part of one rendered on `scene`.
pub type Probe = fn(desc: &SceneDesc, scene: &Scene, frame: u32, k: u32) -> Result<f64, String>;

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    /// The book's table of method settings (docs/src/guide/methods.md) is the registry's: each
    /// setting with the values it admits, what it sets and the methods that read it.
    #[test]
    fn the_books_settings_table_is_the_registrys() {
        let methods = crate::method::methods();
        let mut table =
            String::from("| setting | values | read by | what it sets |\n|---|---|---|---|\n");
        for s in tessera_scene::setting::ALL {
            let readers: Vec<String> = methods
                .iter()
                .filter(|m| m.reads(s))
                .map(|m| format!("`{}`", m.name))
                .collect();
            assert!(
                !readers.is_empty(),
                "integrator.{} is read by no method",
                s.name
            );
            table += &format!(
                "| `integrator.{}` | {} | {} | {} |\n",
                s.name,
                s.kind.describe(),
                readers.join(", "),
                s.doc
            );
        }
        let page =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/src/guide/methods.md");
        let text = std::fs::read_to_string(&page).expect("docs/src/guide/methods.md");
        let (begin, end) = ("<!-- settings:begin -->\n", "<!-- settings:end -->");
        let (Some(i), Some(k)) = (text.find(begin), text.find(end)) else {
            panic!("docs/src/guide/methods.md: no {begin:?} … {end:?} markers");
        };
        if std::env::var_os("TESSERA_BLESS").is_some() {
            let fresh = format!("{}{begin}{table}{}", &text[..i], &text[k..]);
            std::fs::write(&page, fresh).expect("write docs/src/guide/methods.md");
        } else {
            assert_eq!(
                &text[i + begin.len()..k],
                table,
                "docs/src/guide/methods.md is not the registry's settings; \
                 TESSERA_BLESS=1 cargo test -p tessera-render --lib the_books_settings_table rewrites it"
            );
        }
    }
}
