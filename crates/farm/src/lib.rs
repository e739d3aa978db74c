//! The Tessera render farm: a job's settings and plan (`job`), the wire protocol shared by
//! coordinator, workers and clients, the coordinator (HTTP API, job store on SQLite or
//! PostgreSQL, scheduler, the fold of results into frames), the object store its files live in,
//! the worker loop and the client. The farm moves the
//! core's tasks, results and artifacts without knowing one rendering method from another.

pub mod bundle;
pub mod client;
pub mod coordinator;
pub mod job;
pub mod objects;
pub mod protocol;
pub mod store;
pub mod worker;
