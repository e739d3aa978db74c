//! The object store: where a farm's scene bundles, task results, frame checkpoints, step
//! inputs, finished frames and pass artifacts live, by key (`bundles/HASH.tar`,
//! `jobs/7/results/12-3.tswf`, `jobs/7/frame_0001.exr`, `cache/KEY.tswf`, …).
//!
//! Coordinators sharing a job store share it too, so a result that reached one coordinator
//! can be folded by another and a frame written by one is served by all. It is a directory
//! (by default the data directory; for several coordinators, one they all mount, as NFS) or
//! S3 (`s3://bucket/prefix`, configured by the usual `AWS_*` variables), through the
//! `object_store` crate. Writes are whole or not at all: an object is first written to this
//! coordinator's spool directory, then moved (a directory) or uploaded (S3) under its key.

use std::future::Future;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use bytes::Bytes;
use futures_util::StreamExt;
use futures_util::stream::BoxStream;
use object_store::local::LocalFileSystem;
use object_store::path::Path as Key;
use object_store::{ObjectStore, PutPayload, WriteMultipart};

/// Bytes per part of an upload to a remote store.
const PART: usize = 8 << 20;
/// The object holding the store's identity ([`Objects::identity`]).
pub const IDENTITY: &str = "tessera-objects-id";

/// Where objects are kept, and how this process reaches them.
pub struct Objects {
    store: Arc<dyn ObjectStore>,
    /// The directory the objects are files in, for a directory store (they are read and
    /// moved in place).
    dir: Option<PathBuf>,
    /// This process's scratch directory: objects being written, remote objects being read.
    spool: PathBuf,
    /// The store's requests run here, so that blocking code (the fold thread) and async
    /// handlers can both wait for them.
    runtime: Option<tokio::runtime::Runtime>,
    /// The store as the user named it, for messages.
    pub location: String,
}

/// A local copy of an object to read: the object's own file in a directory store, or a
/// download in the spool (removed when this is dropped).
pub struct LocalObject {
    path: PathBuf,
    downloaded: bool,
}

impl LocalObject {
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for LocalObject {
    fn drop(&mut self) {
        if self.downloaded {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

impl Drop for Objects {
    fn drop(&mut self) {
        // Dropped from async code too, where a runtime may not block.
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_background();
        }
    }
}

fn is_not_found(e: &object_store::Error) -> bool {
    matches!(e, object_store::Error::NotFound { .. })
}

impl Objects {
    /// Opens the store at `location` (a directory path, `file:///dir`, or `s3://bucket/prefix`)
    /// with `spool` as this process's scratch directory. Nothing is written: see [`Self::probe`].
    pub fn open(location: &str, spool: &Path) -> anyhow::Result<Objects> {
        let (store, dir): (Arc<dyn ObjectStore>, Option<PathBuf>) = if location.contains("://")
            && !location.starts_with("file://")
        {
            let url = url::Url::parse(location).with_context(|| {
                format!("--objects {location}: expected a directory or s3://bucket/prefix")
            })?;
            if url.scheme() != "s3" {
                anyhow::bail!(
                    "--objects {location}: expected a directory or s3://bucket/prefix, not a {}:// URL",
                    url.scheme()
                );
            }
            // Credentials, region and endpoint from the environment (AWS_ACCESS_KEY_ID,
            // AWS_REGION, AWS_ENDPOINT_URL, AWS_ALLOW_HTTP, …), as the AWS tools read them;
            // a store that does not answer is an error in seconds, not minutes.
            let retry = object_store::RetryConfig {
                max_retries: 3,
                retry_timeout: std::time::Duration::from_secs(20),
                ..Default::default()
            };
            let s3 = object_store::aws::AmazonS3Builder::from_env()
                .with_url(location)
                .with_retry(retry)
                .build()
                .with_context(|| format!("--objects {location}"))?;
            let prefix = Key::from_url_path(url.path())
                .with_context(|| format!("--objects {location}: the prefix"))?;
            let store: Arc<dyn ObjectStore> = if prefix.as_ref().is_empty() {
                Arc::new(s3)
            } else {
                Arc::new(object_store::prefix::PrefixStore::new(s3, prefix))
            };
            (store, None)
        } else {
            let dir = PathBuf::from(location.strip_prefix("file://").unwrap_or(location));
            std::fs::create_dir_all(&dir).with_context(|| {
                format!(
                    "the object store {} cannot be written: creating it",
                    dir.display()
                )
            })?;
            // Deleting an object deletes the directories it leaves empty. (A rename into one
            // being removed fails, and `put_file` then writes through the store instead.)
            let fs = LocalFileSystem::new_with_prefix(&dir)
                .with_context(|| format!("the object store {}", dir.display()))?
                .with_automatic_cleanup(true);
            (Arc::new(fs), Some(dir))
        };
        std::fs::create_dir_all(spool)
            .with_context(|| format!("creating the spool directory {}", spool.display()))?;
        // Made last: a runtime dropped on an error path above would panic in async code.
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("tessera-objects")
            .enable_all()
            .build()
            .context("starting the object store's threads")?;
        Ok(Objects {
            store,
            dir,
            spool: spool.to_path_buf(),
            runtime: Some(runtime),
            location: location.to_owned(),
        })
    }

    /// A store in memory (for tests of what a remote store does: every read a download).
    pub fn in_memory(spool: &Path) -> anyhow::Result<Objects> {
        let mut o = Self::open(&spool.to_string_lossy(), spool)?;
        o.store = Arc::new(object_store::memory::InMemory::new());
        o.dir = None;
        o.location = "memory".into();
        Ok(o)
    }

    /// Writes, reads back and deletes an object named for `who`: a store that cannot be
    /// written is an error naming it, at start-up rather than at the first result.
    pub fn probe(&self, who: &str) -> anyhow::Result<()> {
        let key = format!("probe/{}", who.replace(['/', ':'], "_"));
        let data = Bytes::from(format!("written by {who}"));
        let check = || -> anyhow::Result<()> {
            self.put(&key, data.clone())?;
            let back = self.get(&key)?.context("the object written is not there")?;
            anyhow::ensure!(back == data, "the object written reads back different");
            self.delete(&key)
        };
        check().with_context(|| format!("the object store {} cannot be written", self.location))
    }

    /// The store's identity: an id kept in the store itself ([`IDENTITY`]), `fresh`
    /// (random) written by the first process to ask. Copies of a store share it; two stores
    /// never do.
    pub fn identity(
        &self,
        fresh: impl FnOnce() -> anyhow::Result<String>,
    ) -> anyhow::Result<String> {
        if let Some(id) = self.stored_identity()? {
            anyhow::ensure!(
                !id.is_empty() && id.len() <= 64 && id.bytes().all(|b| b.is_ascii_hexdigit()),
                "the object store {}: {IDENTITY} holds {id:?}, expected a hex id",
                self.location
            );
            return Ok(id);
        }
        let id = fresh()?;
        self.put(IDENTITY, Bytes::from(id.clone()))?;
        // Two first coordinators at once write the same id (`fresh` agrees through the job
        // store); what the store holds is its identity.
        Ok(self.stored_identity()?.unwrap_or(id))
    }

    /// The id the store holds ([`IDENTITY`]), if any.
    fn stored_identity(&self) -> anyhow::Result<Option<String>> {
        Ok(self
            .get(IDENTITY)?
            .map(|b| String::from_utf8_lossy(&b).trim().to_string()))
    }

    /// Waits up to `patience` for the store to hold identity `id`, written by the coordinator
    /// that recorded it in the job store a moment ago: a store that does not show it by then
    /// is not that coordinator's, only at the same location (a local directory of the same
    /// path on another host).
    pub fn await_identity(&self, id: &str, patience: std::time::Duration) -> anyhow::Result<()> {
        let deadline = std::time::Instant::now() + patience;
        loop {
            match self.stored_identity()? {
                Some(held) if held == id => return Ok(()),
                Some(held) => anyhow::bail!(
                    "the object store {} holds id {held:?}, not {id}, the one the job store records for its location",
                    self.location
                ),
                None if std::time::Instant::now() >= deadline => anyhow::bail!(
                    "the object store {} is not the one this farm's job store records at that location (id {id}): it does not hold that id, so it is another store at the same path, such as a local directory on another host; coordinators sharing a job store must share its object store (--objects)",
                    self.location
                ),
                None => std::thread::sleep(std::time::Duration::from_millis(100)),
            }
        }
    }

    /// The spool directory: scratch space of this process, on local disk.
    pub fn spool(&self) -> &Path {
        &self.spool
    }

    /// A fresh file name in the spool.
    pub fn spool_file(&self, name: &str) -> PathBuf {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.spool.join(format!(
            "{}-{n}-{}",
            std::process::id(),
            name.replace('/', "_")
        ))
    }

    /// Runs a request on the store's threads and waits for it (from blocking or async code).
    fn run<T: Send + 'static>(
        &self,
        f: impl Future<Output = object_store::Result<T>> + Send + 'static,
    ) -> object_store::Result<T> {
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let rt = self.runtime.as_ref().ok_or_else(stopped)?;
        rt.spawn(async move {
            let _ = tx.send(f.await);
        });
        rx.recv().map_err(|_| stopped())?
    }

    /// Runs a request on the store's threads, for async code (the caller's thread is free
    /// meanwhile).
    async fn spawn<T: Send + 'static>(
        &self,
        f: impl Future<Output = object_store::Result<T>> + Send + 'static,
    ) -> object_store::Result<T> {
        let rt = self.runtime.as_ref().ok_or_else(stopped)?;
        rt.spawn(f).await.map_err(|_| stopped())?
    }

    fn key(key: &str) -> anyhow::Result<Key> {
        Key::parse(key).with_context(|| format!("object key {key}"))
    }

    /// Stores `data` under `key` (replacing what was there).
    pub fn put(&self, key: &str, data: Bytes) -> anyhow::Result<()> {
        let (store, k) = (self.store.clone(), Self::key(key)?);
        self.run(async move { store.put(&k, PutPayload::from(data)).await })
            .with_context(|| format!("writing {key} to {}", self.location))?;
        Ok(())
    }

    /// Moves the local file `file` under `key`, whole or not at all (it is gone after).
    pub fn put_file(&self, key: &str, file: &Path) -> anyhow::Result<()> {
        let k = Self::key(key)?;
        let done = if let Some(dir) = &self.dir {
            let to = dir.join(key);
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent).with_context(|| parent.display().to_string())?;
            }
            // A rename within one file system; across file systems, an upload.
            std::fs::rename(file, &to).is_ok()
        } else {
            false
        };
        if !done {
            let (store, from) = (self.store.clone(), file.to_path_buf());
            self.run(async move { upload(store, k, from).await })
                .with_context(|| format!("writing {key} to {}", self.location))?;
            let _ = std::fs::remove_file(file);
        }
        Ok(())
    }

    /// Writes an object through a local file: `write` fills the file (which it may also read
    /// back), which is then stored under `key`; returns what `write` did. Nothing is stored if
    /// `write` fails.
    pub fn write<T>(
        &self,
        key: &str,
        write: impl FnOnce(&mut std::fs::File) -> anyhow::Result<T>,
    ) -> anyhow::Result<T> {
        let tmp = self.spool_file(key);
        let result = (|| {
            let mut file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create_new(true)
                .open(&tmp)
                .with_context(|| tmp.display().to_string())?;
            let out = write(&mut file).with_context(|| format!("writing {key}"))?;
            file.sync_all().ok();
            drop(file);
            self.put_file(key, &tmp)?;
            Ok(out)
        })();
        if result.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        result
    }

    /// The object under `key`, whole; `None` if there is none.
    pub fn get(&self, key: &str) -> anyhow::Result<Option<Bytes>> {
        let (store, k) = (self.store.clone(), Self::key(key)?);
        match self.run(async move { store.get(&k).await?.bytes().await }) {
            Ok(b) => Ok(Some(b)),
            Err(e) if is_not_found(&e) => Ok(None),
            Err(e) => Err(e).with_context(|| format!("reading {key} from {}", self.location)),
        }
    }

    /// The object under `key` as a local file to read; `None` if there is none.
    pub fn read(&self, key: &str) -> anyhow::Result<Option<LocalObject>> {
        if let Some(dir) = &self.dir {
            let path = dir.join(key);
            return Ok(path.is_file().then_some(LocalObject {
                path,
                downloaded: false,
            }));
        }
        let (store, k) = (self.store.clone(), Self::key(key)?);
        let path = self.spool_file(key);
        let to = path.clone();
        match self.run(async move { download(store, k, to).await }) {
            Ok(()) => Ok(Some(LocalObject {
                path,
                downloaded: true,
            })),
            Err(e) => {
                let _ = std::fs::remove_file(&path);
                if is_not_found(&e) {
                    Ok(None)
                } else {
                    Err(e).with_context(|| format!("reading {key} from {}", self.location))
                }
            }
        }
    }

    /// The object under `key` as a stream of chunks, with its length; `None` if there is
    /// none.
    pub async fn stream(
        &self,
        key: &str,
    ) -> anyhow::Result<Option<(u64, BoxStream<'static, object_store::Result<Bytes>>)>> {
        let (store, k) = (self.store.clone(), Self::key(key)?);
        match self.spawn(async move { store.get(&k).await }).await {
            Ok(g) => Ok(Some((g.meta.size, g.into_stream()))),
            Err(e) if is_not_found(&e) => Ok(None),
            Err(e) => Err(e).with_context(|| format!("reading {key} from {}", self.location)),
        }
    }

    /// Whether there is an object under `key` (blocking).
    pub fn exists(&self, key: &str) -> anyhow::Result<bool> {
        if let Some(dir) = &self.dir {
            return Ok(dir.join(key).is_file());
        }
        let (store, k) = (self.store.clone(), Self::key(key)?);
        self.found(key, self.run(async move { store.head(&k).await }))
    }

    /// Whether there is an object under `key`, from async code (a remote store's request
    /// does not hold up the caller's thread).
    pub async fn exists_async(&self, key: &str) -> anyhow::Result<bool> {
        if let Some(dir) = &self.dir {
            return Ok(dir.join(key).is_file());
        }
        let (store, k) = (self.store.clone(), Self::key(key)?);
        self.found(key, self.spawn(async move { store.head(&k).await }).await)
    }

    fn found<T>(&self, key: &str, head: object_store::Result<T>) -> anyhow::Result<bool> {
        match head {
            Ok(_) => Ok(true),
            Err(e) if is_not_found(&e) => Ok(false),
            Err(e) => Err(e).with_context(|| format!("looking up {key} in {}", self.location)),
        }
    }

    /// Deletes the object under `key`, if there is one.
    pub fn delete(&self, key: &str) -> anyhow::Result<()> {
        let (store, k) = (self.store.clone(), Self::key(key)?);
        match self.run(async move { store.delete(&k).await }) {
            Err(e) if !is_not_found(&e) => {
                Err(e).with_context(|| format!("deleting {key} from {}", self.location))
            }
            _ => Ok(()),
        }
    }

    /// The keys under `prefix` (a "directory": `jobs/7/steps`).
    pub fn list(&self, prefix: &str) -> anyhow::Result<Vec<String>> {
        let (store, k) = (self.store.clone(), Self::key(prefix)?);
        self.run(async move {
            let mut keys = Vec::new();
            let mut s = store.list(Some(&k));
            while let Some(meta) = s.next().await {
                keys.push(meta?.location.to_string());
            }
            Ok(keys)
        })
        .with_context(|| format!("listing {prefix} in {}", self.location))
    }

    /// Deletes every object under `prefix`.
    pub fn delete_all(&self, prefix: &str) -> anyhow::Result<()> {
        for key in self.list(prefix)? {
            self.delete(&key)?;
        }
        if let Some(dir) = &self.dir {
            // The directories a directory store leaves behind.
            let path = dir.join(prefix);
            if path.is_dir() {
                std::fs::remove_dir_all(&path).with_context(|| path.display().to_string())?;
            }
        }
        Ok(())
    }
}

fn stopped() -> object_store::Error {
    object_store::Error::Generic {
        store: "tessera",
        source: "the object store's threads have stopped".into(),
    }
}

/// Uploads a local file in parts (one request if small).
async fn upload(store: Arc<dyn ObjectStore>, key: Key, from: PathBuf) -> object_store::Result<()> {
    use tokio::io::AsyncReadExt;
    let io = |e: std::io::Error| object_store::Error::Generic {
        store: "tessera",
        source: format!("{}: {e}", from.display()).into(),
    };
    let mut file = tokio::fs::File::open(&from).await.map_err(io)?;
    let len = file.metadata().await.map_err(io)?.len();
    if len <= PART as u64 {
        let mut data = Vec::with_capacity(len as usize);
        file.read_to_end(&mut data).await.map_err(io)?;
        store.put(&key, PutPayload::from(data)).await?;
        return Ok(());
    }
    let mut w = WriteMultipart::new_with_chunk_size(store.put_multipart(&key).await?, PART);
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = match file.read(&mut buf).await {
            Ok(n) => n,
            Err(e) => {
                let _ = w.abort().await;
                return Err(io(e));
            }
        };
        if n == 0 {
            break;
        }
        w.wait_for_capacity(4).await?;
        w.write(&buf[..n]);
    }
    w.finish().await?;
    Ok(())
}

/// Downloads an object to a local file, in the chunks it arrives in.
async fn download(store: Arc<dyn ObjectStore>, key: Key, to: PathBuf) -> object_store::Result<()> {
    use tokio::io::AsyncWriteExt;
    let io = |e: std::io::Error| object_store::Error::Generic {
        store: "tessera",
        source: format!("{}: {e}", to.display()).into(),
    };
    let mut s = store.get(&key).await?.into_stream();
    let mut file = tokio::fs::File::create(&to).await.map_err(io)?;
    while let Some(chunk) = s.next().await {
        file.write_all(&chunk?).await.map_err(io)?;
    }
    file.flush().await.map_err(io)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the coordinator does with objects, on a directory store and on one where every
    /// read is a download (as from S3).
    fn round_trip(o: &Objects) {
        assert!(o.get("jobs/1/a").expect("get").is_none());
        assert!(o.read("jobs/1/a").expect("read").is_none());
        o.put("jobs/1/a", Bytes::from_static(b"alpha"))
            .expect("put");
        // A file larger than one upload part goes up in parts.
        let big: Vec<u8> = (0..PART + 12345).map(|i| (i * 7 % 251) as u8).collect();
        o.write("jobs/1/steps/2-0.input", |f| {
            use std::io::Write;
            f.write_all(&big)?;
            Ok(())
        })
        .expect("write");
        assert_eq!(
            o.get("jobs/1/a").expect("get").as_deref(),
            Some(&b"alpha"[..])
        );
        let local = o
            .read("jobs/1/steps/2-0.input")
            .expect("read")
            .expect("there");
        assert_eq!(std::fs::read(local.path()).expect("local copy"), big);
        let copy = local.path().to_path_buf();
        drop(local);
        assert_eq!(
            copy.exists(),
            o.dir.is_some(),
            "downloads are removed after reading"
        );
        let mut keys = o.list("jobs/1").expect("list");
        keys.sort();
        assert_eq!(keys, ["jobs/1/a", "jobs/1/steps/2-0.input"]);
        assert!(o.exists("jobs/1/a").expect("exists"));
        o.delete("jobs/1/a").expect("delete");
        o.delete("jobs/1/a")
            .expect("deleting what is gone is no error");
        assert!(!o.exists("jobs/1/a").expect("exists"));
        o.delete_all("jobs/1").expect("delete all");
        assert!(o.list("jobs").expect("list").is_empty());
        // A failed write stores nothing and leaves nothing in the spool.
        assert!(o.write::<()>("jobs/2/x", |_| anyhow::bail!("no")).is_err());
        assert!(!o.exists("jobs/2/x").expect("exists"));
        assert_eq!(std::fs::read_dir(o.spool()).expect("spool").count(), 0);
        o.probe("host/127.0.0.1:1").expect("writable");
    }

    #[test]
    fn a_directory_store_keeps_objects_as_files() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let o = Objects::open(
            &tmp.path().join("objects").to_string_lossy(),
            &tmp.path().join("spool"),
        )
        .expect("open");
        round_trip(&o);
        o.put("cache/k.tswf", Bytes::from_static(b"x"))
            .expect("put");
        assert!(tmp.path().join("objects/cache/k.tswf").is_file());
    }

    #[test]
    fn a_remote_store_is_read_through_downloads() {
        let tmp = tempfile::tempdir().expect("temp dir");
        round_trip(&Objects::in_memory(&tmp.path().join("spool")).expect("open"));
    }

    /// A directory that cannot be written fails the probe, naming the store.
    #[test]
    fn a_store_that_cannot_be_written_is_named() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let dir = tmp.path().join("objects");
        let o = Objects::open(&dir.to_string_lossy(), &tmp.path().join("spool")).expect("open");
        std::fs::create_dir_all(dir.join("probe/me")).expect("a directory where the probe goes");
        let e = format!("{:#}", o.probe("me").expect_err("refused"));
        assert!(
            e.contains("cannot be written") && e.contains("objects"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            Objects::open("ftp://host/x", &tmp.path().join("spool"))
                .err()
                .expect("refused")
        );
        assert!(e.contains("ftp://host/x") && e.contains("s3://"), "{e}");
    }
}
