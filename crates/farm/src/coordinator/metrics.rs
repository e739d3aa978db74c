//! Counters for `/metrics`, in the Prometheus text format. Counters reset with the process,
//! as Prometheus expects; gauges are read from the job store at scrape time.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use crate::store::Gauges;

/// Accepted results of one (method, task kind): how many, their bytes as uploaded and before
/// compression, and the pixels they cover.
#[derive(Debug, Clone, Copy, Default)]
struct ResultSizes {
    count: u64,
    wire: u64,
    payload: u64,
    pixels: u64,
}

#[derive(Default)]
pub struct Metrics {
    pub leased: AtomicU64,
    done: AtomicU64,
    pub failed: AtomicU64,
    expired: AtomicU64,
    pub stale_results: AtomicU64,
    frames_written: AtomicU64,
    /// Render time of accepted tasks, microseconds.
    task_micros: AtomicU64,
    results: Mutex<BTreeMap<(String, String), ResultSizes>>,
}

impl Metrics {
    pub fn count_expired(&self) {
        self.expired.fetch_add(1, Relaxed);
    }

    pub fn count_frame(&self) {
        self.frames_written.fetch_add(1, Relaxed);
    }

    /// An accepted result of a `kind` task of `method` covering `pixels`, `seconds` of work.
    pub fn accepted(
        &self,
        method: &str,
        kind: &str,
        (wire, payload): (u64, u64),
        pixels: u64,
        seconds: f64,
    ) {
        self.done.fetch_add(1, Relaxed);
        self.task_micros
            .fetch_add((seconds.max(0.0) * 1e6) as u64, Relaxed);
        let mut r = self.results.lock().unwrap_or_else(|e| e.into_inner());
        let s = r.entry((method.to_string(), kind.to_string())).or_default();
        s.count += 1;
        s.wire += wire;
        s.payload += payload;
        s.pixels += pixels;
    }

    pub fn render(&self, g: &Gauges, workers_alive: u64) -> String {
        let mut out = String::new();
        let mut metric = |name: &str, kind: &str, help: &str, samples: &[(String, f64)]| {
            let _ = writeln!(out, "# HELP tessera_{name} {help}");
            let _ = writeln!(out, "# TYPE tessera_{name} {kind}");
            for (labels, v) in samples {
                let _ = writeln!(out, "tessera_{name}{labels} {v}");
            }
        };
        let one = |v: u64| vec![(String::new(), v as f64)];
        metric(
            "queue_depth",
            "gauge",
            "Tasks waiting for a worker.",
            &one(g.queued),
        );
        metric(
            "tasks_in_flight",
            "gauge",
            "Tasks leased to a worker now.",
            &one(g.leased),
        );
        metric(
            "workers_alive",
            "gauge",
            "Workers seen within the last lease periods.",
            &one(workers_alive),
        );
        let jobs: Vec<(String, f64)> = g
            .jobs
            .iter()
            .map(|(s, n)| (format!("{{state=\"{s}\"}}"), *n as f64))
            .collect();
        metric("jobs", "gauge", "Jobs by state.", &jobs);
        metric(
            "tasks_leased_total",
            "counter",
            "Leases granted.",
            &one(self.leased.load(Relaxed)),
        );
        metric(
            "tasks_done_total",
            "counter",
            "Task results accepted.",
            &one(self.done.load(Relaxed)),
        );
        metric(
            "tasks_failed_total",
            "counter",
            "Task failures reported by workers.",
            &one(self.failed.load(Relaxed)),
        );
        metric(
            "leases_expired_total",
            "counter",
            "Leases that expired and were taken back.",
            &one(self.expired.load(Relaxed)),
        );
        metric(
            "results_stale_total",
            "counter",
            "Results dropped because their lease was no longer current.",
            &one(self.stale_results.load(Relaxed)),
        );
        metric(
            "frames_written_total",
            "counter",
            "Frames folded and written.",
            &one(self.frames_written.load(Relaxed)),
        );
        metric(
            "task_seconds_total",
            "counter",
            "Seconds workers spent rendering accepted tasks.",
            &[(String::new(), self.task_micros.load(Relaxed) as f64 / 1e6)],
        );
        let results = self
            .results
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let by = |f: &dyn Fn(&ResultSizes) -> f64| -> Vec<(String, f64)> {
            results
                .iter()
                .map(|((m, k), s)| (format!("{{method=\"{m}\",kind=\"{k}\"}}"), f(s)))
                .collect()
        };
        metric(
            "results_total",
            "counter",
            "Task results accepted, by method and task kind.",
            &by(&|s| s.count as f64),
        );
        metric(
            "result_bytes_total",
            "counter",
            "Bytes of accepted task results as uploaded (compressed), by method and task kind.",
            &by(&|s| s.wire as f64),
        );
        metric(
            "result_payload_bytes_total",
            "counter",
            "Bytes of accepted task results before compression, by method and task kind.",
            &by(&|s| s.payload as f64),
        );
        metric(
            "result_pixels_total",
            "counter",
            "Pixels the accepted task results cover, by method and task kind.",
            &by(&|s| s.pixels as f64),
        );
        metric(
            "result_payload_bytes_per_task",
            "gauge",
            "Mean payload bytes per accepted task, by method and task kind.",
            &by(&|s| s.payload as f64 / s.count.max(1) as f64),
        );
        metric(
            "result_payload_bytes_per_pixel",
            "gauge",
            "Mean payload bytes per pixel a task covers, by method and task kind (tasks over pixels).",
            &by(&|s| {
                if s.pixels == 0 {
                    0.0
                } else {
                    s.payload as f64 / s.pixels as f64
                }
            }),
        );
        out
    }
}
