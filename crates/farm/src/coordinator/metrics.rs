//! Counters for `/metrics`, in the Prometheus text format. Counters reset with the process,
//! as Prometheus expects; gauges are read from the job store at scrape time.

use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use crate::store::Gauges;

#[derive(Default)]
pub struct Metrics {
    pub leased: AtomicU64,
    pub done: AtomicU64,
    pub failed: AtomicU64,
    pub expired: AtomicU64,
    pub stale_results: AtomicU64,
    pub frames_stitched: AtomicU64,
    /// Render time of accepted tiles, microseconds.
    pub tile_micros: AtomicU64,
}

impl Metrics {
    pub fn add_tile_seconds(&self, s: f64) {
        self.tile_micros
            .fetch_add((s.max(0.0) * 1e6) as u64, Relaxed);
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
            "frames_stitched_total",
            "counter",
            "Frames stitched and written.",
            &one(self.frames_stitched.load(Relaxed)),
        );
        metric(
            "tile_seconds_total",
            "counter",
            "Seconds workers spent rendering accepted tiles.",
            &[(String::new(), self.tile_micros.load(Relaxed) as f64 / 1e6)],
        );
        out
    }
}
