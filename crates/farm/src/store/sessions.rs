//! Browser sessions: a dashboard user who gave the client token holds a random session id in
//! an HttpOnly cookie, and a second random value, the CSRF token, that the page sends back in
//! a header with every request that changes something.

use super::db::{Optional, params};

use super::{Result, Store};

/// A browser session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Session {
    pub id: String,
    pub csrf: String,
    pub expires_ms: i64,
}

impl Store {
    /// Records a new session (and forgets expired ones).
    pub fn insert_session(&self, s: &Session, now: i64) -> Result<()> {
        let conn = self.conn()?;
        conn.execute("DELETE FROM sessions WHERE expires_ms < ?1", params![now])?;
        conn.execute(
            "INSERT INTO sessions (id, csrf, created_ms, expires_ms) VALUES (?1, ?2, ?3, ?4)",
            params![s.id, s.csrf, now, s.expires_ms],
        )?;
        Ok(())
    }

    /// The session with this id, if it has not expired.
    pub fn session(&self, id: &str, now: i64) -> Result<Option<Session>> {
        Ok(self
            .conn()?
            .query_row(
                "SELECT id, csrf, expires_ms FROM sessions WHERE id = ?1 AND expires_ms >= ?2",
                params![id, now],
                |r| {
                    Ok(Session {
                        id: r.get(0)?,
                        csrf: r.get(1)?,
                        expires_ms: r.get(2)?,
                    })
                },
            )
            .optional()?)
    }

    /// Ends a session (logout).
    pub fn delete_session(&self, id: &str) -> Result<()> {
        self.conn()?
            .execute("DELETE FROM sessions WHERE id = ?1", params![id])?;
        Ok(())
    }
}
