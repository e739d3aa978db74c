//! PostgreSQL: a pool of `tokio-postgres` connections on the store's own runtime, and the
//! conversions between its values and [`Value`].

use super::*;
use bytes::BytesMut;
use tokio_postgres::types::{IsNull, ToSql, Type, to_sql_checked};

/// Connections at most (each coordinator).
const MAX_CONNECTIONS: usize = 16;
/// How long an operation waits for a connection when all are in use.
const WAIT: Duration = Duration::from_secs(30);

pub struct Pool {
    /// Dropped without blocking (see `Drop`): the store may be dropped inside a runtime.
    rt: Option<tokio::runtime::Runtime>,
    config: tokio_postgres::Config,
    /// Where, for errors: the URL's host and database, never its password.
    place: String,
    idle: Mutex<Idle>,
    freed: Condvar,
}

struct Idle {
    conns: Vec<Arc<PgConn>>,
    open: usize,
}

struct PgConn {
    client: tokio_postgres::Client,
    statements: Mutex<HashMap<String, tokio_postgres::Statement>>,
}

/// A connection lent from the pool; back to it when dropped.
pub struct Lent<'a> {
    pool: &'a Pool,
    conn: Option<Arc<PgConn>>,
}

impl Drop for Pool {
    fn drop(&mut self) {
        if let Some(rt) = self.rt.take() {
            rt.shutdown_background();
        }
    }
}

impl Drop for Lent<'_> {
    fn drop(&mut self) {
        if let Some(c) = self.conn.take() {
            let mut idle = self.pool.idle.lock().unwrap_or_else(|e| e.into_inner());
            if c.client.is_closed() {
                idle.open -= 1;
            } else {
                idle.conns.push(c);
            }
            self.pool.freed.notify_one();
        }
    }
}

impl Pool {
    pub fn connect(url: &str) -> Result<Pool> {
        let mut config: tokio_postgres::Config = url.parse().map_err(|e| {
            StoreError::Config(format!("the store URL is not a PostgreSQL URL: {e}"))
        })?;
        if config.get_connect_timeout().is_none() {
            config.connect_timeout(Duration::from_secs(10));
        }
        config.keepalives_idle(Duration::from_secs(30));
        let hosts: Vec<String> = config
            .get_hosts()
            .iter()
            .map(|h| match h {
                tokio_postgres::config::Host::Tcp(h) => h.clone(),
                tokio_postgres::config::Host::Unix(p) => p.display().to_string(),
            })
            .collect();
        let place = format!(
            "PostgreSQL database {:?} on {} as user {:?}",
            config.get_dbname().unwrap_or("(the user's)"),
            if hosts.is_empty() {
                "localhost".to_owned()
            } else {
                hosts.join(",")
            },
            config.get_user().unwrap_or("(the OS user)"),
        );
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("store-postgres")
            .enable_all()
            .build()
            .map_err(|e| StoreError::Config(format!("starting the store's runtime: {e}")))?;
        let pool = Pool {
            rt: Some(rt),
            config,
            place,
            idle: Mutex::new(Idle {
                conns: Vec::new(),
                open: 0,
            }),
            freed: Condvar::new(),
        };
        // Connect once now, so that a wrong URL or password fails at start-up.
        drop(pool.lend()?);
        Ok(pool)
    }

    /// Runs `fut` on the store's runtime and waits for it (from any thread, in a runtime
    /// or not).
    fn run<T: Send + 'static>(
        &self,
        fut: impl std::future::Future<Output = T> + Send + 'static,
    ) -> Result<T> {
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let rt = self
            .rt
            .as_ref()
            .ok_or_else(|| StoreError::Config("the store is closed".into()))?;
        rt.spawn(async move {
            let _ = tx.send(fut.await);
        });
        blocking(|| rx.recv()).map_err(|_| StoreError::Config("the store's runtime stopped".into()))
    }

    pub fn lend(&self) -> Result<Lent<'_>> {
        let deadline = std::time::Instant::now() + WAIT;
        let mut idle = self.idle.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            while let Some(c) = idle.conns.pop() {
                if !c.client.is_closed() {
                    return Ok(Lent {
                        pool: self,
                        conn: Some(c),
                    });
                }
                idle.open -= 1;
            }
            if idle.open < MAX_CONNECTIONS {
                idle.open += 1;
                drop(idle);
                return match self.open() {
                    Ok(c) => Ok(Lent {
                        pool: self,
                        conn: Some(Arc::new(c)),
                    }),
                    Err(e) => {
                        self.idle.lock().unwrap_or_else(|e| e.into_inner()).open -= 1;
                        Err(e)
                    }
                };
            }
            let now = std::time::Instant::now();
            if now >= deadline {
                return Err(StoreError::Config(format!(
                    "all {MAX_CONNECTIONS} connections to the {} stayed busy for {} s",
                    self.place,
                    WAIT.as_secs()
                )));
            }
            idle = blocking(|| self.freed.wait_timeout(idle, deadline - now))
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    /// A connection of its own that listens on `channel` for as long as the pool lives,
    /// reconnecting after a second when it drops.
    pub fn listen(&self, channel: &'static str, on: Arc<dyn Fn() + Send + Sync>) {
        let Some(rt) = self.rt.as_ref() else { return };
        let config = self.config.clone();
        rt.spawn(async move {
            loop {
                match config.connect(tokio_postgres::NoTls).await {
                    Ok((client, mut connection)) => {
                        let heard = on.clone();
                        let poll = tokio::spawn(async move {
                            loop {
                                match std::future::poll_fn(|cx| connection.poll_message(cx))
                                    .await
                                {
                                    Some(Ok(tokio_postgres::AsyncMessage::Notification(_))) => {
                                        heard()
                                    }
                                    Some(Ok(_)) => {}
                                    Some(Err(e)) => {
                                        tracing::warn!(error = %e, channel, "listening to the job store");
                                        break;
                                    }
                                    None => break,
                                }
                            }
                        });
                        match client.batch_execute(&format!("LISTEN {channel}")).await {
                            Ok(()) => on(),
                            Err(e) => tracing::warn!(error = %e, channel, "LISTEN"),
                        }
                        let _ = poll.await;
                    }
                    Err(e) => tracing::warn!(error = %e, channel, "connecting to listen"),
                }
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        });
    }

    fn open(&self) -> Result<PgConn> {
        let config = self.config.clone();
        let (client, connection) = self
            .run(async move { config.connect(tokio_postgres::NoTls).await })?
            .map_err(|e| StoreError::Connect {
                place: self.place.clone(),
                source: e,
            })?;
        let rt = self.rt.as_ref().expect("running");
        rt.spawn(async move {
            if let Err(e) = connection.await {
                tracing::warn!(error = %e, "a connection to the job store ended");
            }
        });
        Ok(PgConn {
            client,
            statements: Mutex::new(HashMap::new()),
        })
    }
}

impl Lent<'_> {
    fn conn(&self) -> Arc<PgConn> {
        self.conn.clone().expect("lent until dropped")
    }

    pub fn batch(&self, sql: &str) -> Result<()> {
        let c = self.conn();
        let sql = sql.to_owned();
        Ok(self
            .pool
            .run(async move { c.client.batch_execute(&sql).await })??)
    }

    pub fn execute(&self, sql: &str, params: Vec<Value>) -> Result<usize> {
        match self.prepared(sql, params, false)? {
            Answer::Count(n) => Ok(n as usize),
            Answer::Rows(rows) => Ok(rows.len()),
        }
    }

    pub fn query(&self, sql: &str, params: Vec<Value>) -> Result<Vec<Row>> {
        match self.prepared(sql, params, true)? {
            Answer::Rows(rows) => rows.iter().map(row).collect(),
            Answer::Count(_) => Ok(Vec::new()),
        }
    }

    /// Runs `sql` as a prepared (and cached) statement with `params` bound: its rows, or the
    /// number of rows it changed.
    fn prepared(&self, sql: &str, params: Vec<Value>, rows: bool) -> Result<Answer> {
        let c = self.conn();
        let owned = sql.to_owned();
        self.pool
            .run(async move {
                let stmt = c.prepared(&owned).await?;
                let refs: Vec<&(dyn ToSql + Sync)> =
                    params.iter().map(|p| p as &(dyn ToSql + Sync)).collect();
                Ok(if rows {
                    Answer::Rows(c.client.query(&stmt, &refs).await?)
                } else {
                    Answer::Count(c.client.execute(&stmt, &refs).await?)
                })
            })?
            .map_err(|e| StoreError::statement(sql, e))
    }
}

/// What a statement gave back.
enum Answer {
    Rows(Vec<tokio_postgres::Row>),
    Count(u64),
}

impl PgConn {
    async fn prepared(
        &self,
        sql: &str,
    ) -> std::result::Result<tokio_postgres::Statement, tokio_postgres::Error> {
        if let Some(s) = self
            .statements
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(sql)
        {
            return Ok(s.clone());
        }
        let s = self.client.prepare(sql).await?;
        self.statements
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(sql.to_owned(), s.clone());
        Ok(s)
    }
}

/// Runs `f`, which waits for the database, telling a multi-threaded tokio runtime that
/// this thread blocks so that it moves its other tasks to another thread: a coordinator's
/// requests wait for PostgreSQL side by side rather than one per core.
fn blocking<T>(f: impl FnOnce() -> T) -> T {
    use tokio::runtime::{Handle, RuntimeFlavor};
    match Handle::try_current() {
        Ok(h) if h.runtime_flavor() == RuntimeFlavor::MultiThread => tokio::task::block_in_place(f),
        _ => f(),
    }
}

fn row(r: &tokio_postgres::Row) -> Result<Row> {
    let mut values = Vec::with_capacity(r.len());
    for (i, col) in r.columns().iter().enumerate() {
        let t = col.type_();
        let v = match *t {
            Type::INT8 => r.try_get::<_, Option<i64>>(i)?.map(Value::Int),
            Type::INT4 => r
                .try_get::<_, Option<i32>>(i)?
                .map(|v| Value::Int(v.into())),
            Type::INT2 => r
                .try_get::<_, Option<i16>>(i)?
                .map(|v| Value::Int(v.into())),
            Type::BOOL => r
                .try_get::<_, Option<bool>>(i)?
                .map(|v| Value::Int(v.into())),
            Type::FLOAT8 => r.try_get::<_, Option<f64>>(i)?.map(Value::Real),
            Type::FLOAT4 => r
                .try_get::<_, Option<f32>>(i)?
                .map(|v| Value::Real(v.into())),
            Type::NUMERIC => r.try_get::<_, Option<Numeric>>(i)?.map(|n| n.0),
            Type::TEXT | Type::VARCHAR | Type::BPCHAR | Type::NAME => {
                r.try_get::<_, Option<String>>(i)?.map(Value::Text)
            }
            _ => {
                return Err(StoreError::Corrupt(format!(
                    "column {:?} has PostgreSQL type {t}, which the store does not read",
                    col.name()
                )));
            }
        };
        values.push(v.unwrap_or(Value::Null));
    }
    Ok(Row { values })
}

/// PostgreSQL's `numeric` (what `SUM` of integers gives): an integer when it has no
/// fraction digits, else a float.
struct Numeric(Value);

impl<'a> tokio_postgres::types::FromSql<'a> for Numeric {
    fn from_sql(
        _: &Type,
        raw: &'a [u8],
    ) -> std::result::Result<Self, Box<dyn std::error::Error + Sync + Send>> {
        // Binary format: ndigits, weight, sign, dscale (i16 each), then base-10000 digits.
        let word =
            |i: usize| -> std::result::Result<i16, Box<dyn std::error::Error + Sync + Send>> {
                raw.get(2 * i..2 * i + 2)
                    .map(|b| i16::from_be_bytes([b[0], b[1]]))
                    .ok_or_else(|| "a numeric value ends early".into())
            };
        let (ndigits, weight, sign, dscale) = (word(0)?, word(1)?, word(2)? as u16, word(3)?);
        if sign == 0xC000 {
            return Ok(Numeric(Value::Real(f64::NAN)));
        }
        let mut x = 0f64;
        for d in 0..ndigits as usize {
            x += word(4 + d)? as f64 * 10000f64.powi(weight as i32 - d as i32);
        }
        if sign == 0x4000 {
            x = -x;
        }
        Ok(Numeric(if dscale == 0 && x.abs() < 9.0e15 {
            Value::Int(x.round() as i64)
        } else {
            Value::Real(x)
        }))
    }

    fn accepts(ty: &Type) -> bool {
        *ty == Type::NUMERIC
    }
}

impl ToSql for Value {
    fn to_sql(
        &self,
        ty: &Type,
        out: &mut BytesMut,
    ) -> std::result::Result<IsNull, Box<dyn std::error::Error + Sync + Send>> {
        let int = |i: i64, out: &mut BytesMut| match *ty {
            Type::INT8 => i.to_sql(ty, out),
            Type::INT4 => i32::try_from(i)?.to_sql(ty, out),
            Type::INT2 => i16::try_from(i)?.to_sql(ty, out),
            Type::FLOAT8 => (i as f64).to_sql(ty, out),
            Type::FLOAT4 => (i as f32).to_sql(ty, out),
            Type::BOOL => (i != 0).to_sql(ty, out),
            _ => i.to_string().to_sql(&Type::TEXT, out),
        };
        match self {
            Value::Null => Ok(IsNull::Yes),
            Value::Int(i) => int(*i, out),
            Value::Real(f) => match *ty {
                Type::FLOAT8 => f.to_sql(ty, out),
                Type::FLOAT4 => (*f as f32).to_sql(ty, out),
                Type::INT8 | Type::INT4 | Type::INT2 | Type::BOOL if f.fract() == 0.0 => {
                    int(*f as i64, out)
                }
                _ => f.to_string().to_sql(&Type::TEXT, out),
            },
            Value::Text(s) => s.to_sql(&Type::TEXT, out),
        }
    }

    fn accepts(_: &Type) -> bool {
        true
    }

    to_sql_checked!();
}
