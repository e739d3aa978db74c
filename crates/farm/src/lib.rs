//! The Tessera render farm: how an image is made from a job (`job`), the wire protocol and
//! codecs shared by coordinator, workers and clients, the coordinator (HTTP API, SQLite job
//! store, scheduler, stitcher), the worker loop and the client.

pub mod bdpt;
pub mod bundle;
pub mod client;
pub mod codec;
pub mod coordinator;
pub mod job;
pub mod passes;
pub mod progressive;
pub mod protocol;
pub mod sppm;
pub mod store;
pub mod subsurface;
pub mod worker;
