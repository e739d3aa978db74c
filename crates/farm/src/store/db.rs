//! The SQL the store speaks, on either database: the embedded SQLite (one connection behind a
//! mutex) or PostgreSQL (a pool of connections, driven by `tokio-postgres` on a runtime of the
//! store's own, so the store stays synchronous and callable from anywhere).
//!
//! Statements are written once, in the SQL both databases read (`?N` parameters, `ON CONFLICT`,
//! `RETURNING`); for PostgreSQL `?N` becomes `$N`, and the schema's `INTEGER` / `REAL` /
//! `AUTOINCREMENT` become `BIGINT` / `DOUBLE PRECISION` / identity columns ([`Dialect::ddl`]).
//! Rows come back as [`Value`]s, so a caller reads them the same way from either.
//!
//! A write is a closure run in one transaction ([`Db::write`]). On PostgreSQL it runs at
//! SERIALIZABLE isolation and is run again when the database reports a serialization failure
//! or a deadlock, so several coordinators sharing a database see the same one-at-a-time store
//! the embedded SQLite gives one coordinator.

use std::collections::HashMap;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use super::{Result, StoreError};

/// A value bound to a parameter or read from a column.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Null,
    Int(i64),
    Real(f64),
    Text(String),
}

/// A Rust value as a parameter.
pub trait ToValue {
    fn to_value(&self) -> Value;
}

macro_rules! int_to_value {
    ($($t:ty),*) => {$(
        impl ToValue for $t {
            fn to_value(&self) -> Value {
                Value::Int(*self as i64)
            }
        }
    )*};
}
int_to_value!(i64, i32, u32, u16, u8, usize, u64);

impl ToValue for bool {
    fn to_value(&self) -> Value {
        Value::Int(*self as i64)
    }
}
impl ToValue for f64 {
    fn to_value(&self) -> Value {
        Value::Real(*self)
    }
}
impl ToValue for f32 {
    fn to_value(&self) -> Value {
        Value::Real(*self as f64)
    }
}
impl ToValue for str {
    fn to_value(&self) -> Value {
        Value::Text(self.to_owned())
    }
}
impl ToValue for String {
    fn to_value(&self) -> Value {
        Value::Text(self.clone())
    }
}
impl ToValue for Value {
    fn to_value(&self) -> Value {
        self.clone()
    }
}
impl<T: ToValue + ?Sized> ToValue for &T {
    fn to_value(&self) -> Value {
        (**self).to_value()
    }
}
impl<T: ToValue> ToValue for Option<T> {
    fn to_value(&self) -> Value {
        self.as_ref().map_or(Value::Null, ToValue::to_value)
    }
}

/// Parameters of a statement: `params![a, b, c]`.
macro_rules! params {
    () => { &[] as &[&dyn $crate::store::db::ToValue] };
    ($($p:expr),+ $(,)?) => { &[$(&$p as &dyn $crate::store::db::ToValue),+] as &[&dyn $crate::store::db::ToValue] };
}
pub(crate) use params;

/// A column's value as a Rust value.
pub trait FromValue: Sized {
    fn from_value(v: &Value) -> std::result::Result<Self, String>;
}

macro_rules! int_from_value {
    ($($t:ty),*) => {$(
        impl FromValue for $t {
            fn from_value(v: &Value) -> std::result::Result<Self, String> {
                match v {
                    Value::Int(i) => <$t>::try_from(*i).map_err(|_| format!("{i} is out of range")),
                    Value::Real(r) if r.fract() == 0.0 => <$t>::try_from(*r as i64)
                        .map_err(|_| format!("{r} is out of range")),
                    other => Err(format!("expected an integer, found {other:?}")),
                }
            }
        }
    )*};
}
int_from_value!(i64, i32, u32, u16, u8, usize, u64);

impl FromValue for bool {
    fn from_value(v: &Value) -> std::result::Result<Self, String> {
        i64::from_value(v).map(|i| i != 0)
    }
}
impl FromValue for f64 {
    fn from_value(v: &Value) -> std::result::Result<Self, String> {
        match v {
            Value::Int(i) => Ok(*i as f64),
            Value::Real(r) => Ok(*r),
            other => Err(format!("expected a number, found {other:?}")),
        }
    }
}
impl FromValue for f32 {
    fn from_value(v: &Value) -> std::result::Result<Self, String> {
        f64::from_value(v).map(|f| f as f32)
    }
}
impl FromValue for String {
    fn from_value(v: &Value) -> std::result::Result<Self, String> {
        match v {
            Value::Text(s) => Ok(s.clone()),
            other => Err(format!("expected text, found {other:?}")),
        }
    }
}
impl<T: FromValue> FromValue for Option<T> {
    fn from_value(v: &Value) -> std::result::Result<Self, String> {
        match v {
            Value::Null => Ok(None),
            v => T::from_value(v).map(Some),
        }
    }
}

/// One row of a result.
#[derive(Debug)]
pub struct Row {
    values: Vec<Value>,
}

impl Row {
    /// Column `i` (from 0) as a `T`; an error naming the column when it is not one.
    pub fn get<T: FromValue>(&self, i: usize) -> Result<T> {
        let v = self
            .values
            .get(i)
            .ok_or_else(|| StoreError::Corrupt(format!("no column {i} in a row")))?;
        T::from_value(v).map_err(|e| StoreError::Corrupt(format!("column {i}: {e}")))
    }
}

/// `query_row(…).optional()`: no row is `None` rather than an error.
pub trait Optional<T> {
    fn optional(self) -> Result<Option<T>>;
}

impl<T> Optional<T> for Result<T> {
    fn optional(self) -> Result<Option<T>> {
        match self {
            Ok(t) => Ok(Some(t)),
            Err(StoreError::NoRow) => Ok(None),
            Err(e) => Err(e),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dialect {
    Sqlite,
    Postgres,
}

impl Dialect {
    /// Schema text written for SQLite, in this dialect.
    pub fn ddl(self, sql: &str) -> String {
        match self {
            Dialect::Sqlite => sql.to_owned(),
            Dialect::Postgres => sql
                .replace(
                    "INTEGER PRIMARY KEY AUTOINCREMENT",
                    "BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY",
                )
                .replace(" INTEGER", " BIGINT")
                .replace(" REAL", " DOUBLE PRECISION"),
        }
    }

    /// What ends a query for a queue's next row: PostgreSQL locks the row it returns and
    /// passes over rows another transaction holds (`FOR UPDATE SKIP LOCKED`), so coordinators
    /// leasing at once take different tasks; SQLite has one writer and needs nothing.
    pub fn skip_locked(self) -> &'static str {
        match self {
            Dialect::Sqlite => "",
            Dialect::Postgres => " FOR UPDATE SKIP LOCKED",
        }
    }

    /// A statement written with `?N` parameters, in this dialect.
    fn statement(self, sql: &str) -> String {
        match self {
            Dialect::Sqlite => sql.to_owned(),
            Dialect::Postgres => {
                let mut out = String::with_capacity(sql.len());
                let mut chars = sql.chars().peekable();
                while let Some(c) = chars.next() {
                    if c == '?' && chars.peek().is_some_and(|d| d.is_ascii_digit()) {
                        out.push('$');
                    } else {
                        out.push(c);
                    }
                }
                out
            }
        }
    }
}

/// The store's database.
pub struct Db {
    backend: Backend,
}

enum Backend {
    Sqlite(Mutex<rusqlite::Connection>),
    Postgres(pg::Pool),
}

/// A connection lent for one operation: statements in autocommit, or in a transaction when
/// given by [`Db::write`].
pub struct Conn<'a> {
    inner: ConnInner<'a>,
}

enum ConnInner<'a> {
    Sqlite(MutexGuard<'a, rusqlite::Connection>),
    Postgres(pg::Lent<'a>),
}

impl Db {
    pub fn sqlite(conn: rusqlite::Connection) -> Db {
        conn.set_prepared_statement_cache_capacity(64);
        Db {
            backend: Backend::Sqlite(Mutex::new(conn)),
        }
    }

    /// Connects to PostgreSQL at `url` (a libpq URL or key=value string).
    pub fn postgres(url: &str) -> Result<Db> {
        Ok(Db {
            backend: Backend::Postgres(pg::Pool::connect(url)?),
        })
    }

    pub fn dialect(&self) -> Dialect {
        match self.backend {
            Backend::Sqlite(_) => Dialect::Sqlite,
            Backend::Postgres(_) => Dialect::Postgres,
        }
    }

    /// Calls `on` whenever a `NOTIFY channel` is sent by anyone sharing the database (and once
    /// after each (re)connection, for what was sent while disconnected); nothing on SQLite,
    /// which nobody shares.
    pub fn listen(&self, channel: &'static str, on: Arc<dyn Fn() + Send + Sync>) {
        if let Backend::Postgres(p) = &self.backend {
            p.listen(channel, on);
        }
    }

    /// A connection for statements that need no transaction of their own.
    pub fn conn(&self) -> Result<Conn<'_>> {
        Ok(Conn {
            inner: match &self.backend {
                // A panic while holding the lock leaves SQLite consistent (transactions roll
                // back).
                Backend::Sqlite(m) => {
                    ConnInner::Sqlite(m.lock().unwrap_or_else(|e| e.into_inner()))
                }
                Backend::Postgres(p) => ConnInner::Postgres(p.lend()?),
            },
        })
    }

    /// Runs `f` in one transaction: committed when it returns `Ok`, rolled back when it
    /// returns an error. On PostgreSQL (SERIALIZABLE) `f` runs again, on a new transaction,
    /// when the database could not serialise it with another coordinator's.
    pub fn write<T>(&self, f: impl FnMut(&Conn) -> Result<T>) -> Result<T> {
        self.transaction("BEGIN ISOLATION LEVEL SERIALIZABLE", f)
    }

    /// [`Db::write`] for a transaction that orders itself with row locks, on PostgreSQL at READ
    /// COMMITTED (where each statement sees what committed before it): taking a queue's next
    /// row locked as it is read (`FOR UPDATE SKIP LOCKED`, [`Dialect::skip_locked`]), so that
    /// transactions taking rows at once take different ones; or updating a counter row before
    /// reading what the counter counts, so that transactions updating it at once wait for each
    /// other instead of failing each other (SERIALIZABLE fails all but one of them).
    pub fn write_row_locked<T>(&self, f: impl FnMut(&Conn) -> Result<T>) -> Result<T> {
        self.transaction("BEGIN ISOLATION LEVEL READ COMMITTED", f)
    }

    fn transaction<T>(
        &self,
        postgres_begin: &str,
        mut f: impl FnMut(&Conn) -> Result<T>,
    ) -> Result<T> {
        let conn = self.conn()?;
        let begin = match self.dialect() {
            Dialect::Sqlite => "BEGIN",
            Dialect::Postgres => postgres_begin,
        };
        let mut attempt = 0u32;
        loop {
            conn.execute_batch(begin)?;
            let r = f(&conn).and_then(|t| conn.execute_batch("COMMIT").map(|()| t));
            match r {
                Ok(t) => return Ok(t),
                Err(e) => {
                    // Rolling back a transaction the database already ended is harmless.
                    let _ = conn.execute_batch("ROLLBACK");
                    attempt += 1;
                    if e.is_serialization_failure() && attempt < 50 {
                        std::thread::sleep(Duration::from_millis(
                            (1 + (attempt as u64 * 7919 + std::process::id() as u64) % 20)
                                * attempt.min(5) as u64,
                        ));
                        continue;
                    }
                    return Err(e);
                }
            }
        }
    }
}

impl Conn<'_> {
    pub fn dialect(&self) -> Dialect {
        match self.inner {
            ConnInner::Sqlite(_) => Dialect::Sqlite,
            ConnInner::Postgres(_) => Dialect::Postgres,
        }
    }

    /// Runs statements without parameters (separated by `;`).
    pub fn execute_batch(&self, sql: &str) -> Result<()> {
        match &self.inner {
            ConnInner::Sqlite(c) => Ok(c.execute_batch(sql)?),
            ConnInner::Postgres(c) => c.batch(sql),
        }
    }

    /// Runs a statement; the number of rows it changed.
    pub fn execute(&self, sql: &str, params: &[&dyn ToValue]) -> Result<usize> {
        match &self.inner {
            ConnInner::Sqlite(c) => {
                let mut stmt = c.prepare_cached(sql)?;
                Ok(stmt.execute(rusqlite::params_from_iter(
                    params.iter().map(|p| p.to_value()),
                ))?)
            }
            ConnInner::Postgres(c) => c.execute(&self.dialect().statement(sql), values(params)),
        }
    }

    /// Every row of a query, each read by `f`.
    pub fn query_map<T>(
        &self,
        sql: &str,
        params: &[&dyn ToValue],
        mut f: impl FnMut(&Row) -> Result<T>,
    ) -> Result<Vec<T>> {
        self.rows(sql, params)?.iter().map(&mut f).collect()
    }

    /// The first row of a query, read by `f`; [`StoreError::NoRow`] when there is none (see
    /// [`Optional::optional`]).
    pub fn query_row<T>(
        &self,
        sql: &str,
        params: &[&dyn ToValue],
        f: impl FnOnce(&Row) -> Result<T>,
    ) -> Result<T> {
        match self.rows(sql, params)?.first() {
            Some(row) => f(row),
            None => Err(StoreError::NoRow),
        }
    }

    fn rows(&self, sql: &str, params: &[&dyn ToValue]) -> Result<Vec<Row>> {
        match &self.inner {
            ConnInner::Sqlite(c) => {
                let mut stmt = c.prepare_cached(sql)?;
                let n = stmt.column_count();
                let mut rows = stmt.query(rusqlite::params_from_iter(
                    params.iter().map(|p| p.to_value()),
                ))?;
                let mut out = Vec::new();
                while let Some(r) = rows.next()? {
                    let mut values = Vec::with_capacity(n);
                    for i in 0..n {
                        use rusqlite::types::ValueRef;
                        values.push(match r.get_ref(i)? {
                            ValueRef::Null => Value::Null,
                            ValueRef::Integer(i) => Value::Int(i),
                            ValueRef::Real(f) => Value::Real(f),
                            ValueRef::Text(t) => {
                                Value::Text(String::from_utf8_lossy(t).into_owned())
                            }
                            ValueRef::Blob(_) => {
                                return Err(StoreError::Corrupt(format!(
                                    "column {i} of `{sql}` holds a blob"
                                )));
                            }
                        });
                    }
                    out.push(Row { values });
                }
                Ok(out)
            }
            ConnInner::Postgres(c) => c.query(&self.dialect().statement(sql), values(params)),
        }
    }
}

fn values(params: &[&dyn ToValue]) -> Vec<Value> {
    params.iter().map(|p| p.to_value()).collect()
}

impl rusqlite::ToSql for Value {
    fn to_sql(&self) -> rusqlite::Result<rusqlite::types::ToSqlOutput<'_>> {
        use rusqlite::types::{ToSqlOutput, ValueRef};
        Ok(ToSqlOutput::Borrowed(match self {
            Value::Null => ValueRef::Null,
            Value::Int(i) => ValueRef::Integer(*i),
            Value::Real(f) => ValueRef::Real(*f),
            Value::Text(s) => ValueRef::Text(s.as_bytes()),
        }))
    }
}

impl StoreError {
    /// Whether running the transaction again may succeed (PostgreSQL's serialization failure
    /// or deadlock).
    fn is_serialization_failure(&self) -> bool {
        use tokio_postgres::error::SqlState;
        match self {
            StoreError::Postgres(e) | StoreError::Statement { source: e, .. } => {
                e.code().is_some_and(|c| {
                    *c == SqlState::T_R_SERIALIZATION_FAILURE
                        || *c == SqlState::T_R_DEADLOCK_DETECTED
                })
            }
            _ => false,
        }
    }
}

/// PostgreSQL: a pool of `tokio-postgres` connections on the store's own runtime.
mod pg;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statements_and_schema_in_postgres_dialect() {
        assert_eq!(
            Dialect::Postgres.statement("SELECT a FROM t WHERE b = ?1 AND c = ?12 AND d = '?'"),
            "SELECT a FROM t WHERE b = $1 AND c = $12 AND d = '?'"
        );
        assert_eq!(
            Dialect::Postgres.ddl(
                "CREATE TABLE t (id INTEGER PRIMARY KEY AUTOINCREMENT, n INTEGER NOT NULL, x REAL)"
            ),
            "CREATE TABLE t (id BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY, n BIGINT NOT NULL, x DOUBLE PRECISION)"
        );
    }
}
