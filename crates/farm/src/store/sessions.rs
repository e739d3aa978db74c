//! Browser sessions: a dashboard user who gave the client token holds a random session id in
//! an HttpOnly cookie, and a second random value, the CSRF token, that the page sends back in
//! a header with every request that changes something.

use super::db::{Optional, params};

use super::{Result, Store, StoreError};
use crate::protocol::Role;

/// A browser session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Session {
    pub id: String,
    pub csrf: String,
    pub expires_ms: i64,
    /// Whose it is: the name and role of the token it logged in with.
    pub user: String,
    pub role: Role,
}

impl Store {
    /// Records a new session (and forgets expired ones).
    pub fn insert_session(&self, s: &Session, now: i64) -> Result<()> {
        let conn = self.conn()?;
        conn.execute("DELETE FROM sessions WHERE expires_ms < ?1", params![now])?;
        conn.execute(
            "INSERT INTO sessions (id, csrf, created_ms, expires_ms, user_name, role)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            params![s.id, s.csrf, now, s.expires_ms, s.user, s.role.as_str()],
        )?;
        Ok(())
    }

    /// The session with this id, if it has not expired and its user's token is still the
    /// live one it logged in with (a user revoked or given a new token since ends it).
    /// `admin` is the coordinator's own client token, which is not a user of the table.
    pub fn session(&self, id: &str, now: i64) -> Result<Option<Session>> {
        self.conn()?
            .query_row(
                "SELECT s.id, s.csrf, s.expires_ms, s.user_name, s.role FROM sessions s
                 WHERE s.id = ?1 AND s.expires_ms >= ?2
                   AND (s.user_name = 'admin' OR EXISTS (SELECT 1 FROM users u
                        WHERE u.name = s.user_name AND u.revoked_ms IS NULL
                          AND u.created_ms <= s.created_ms))",
                params![id, now],
                |r| {
                    let role: String = r.get(4)?;
                    Ok(Session {
                        id: r.get(0)?,
                        csrf: r.get(1)?,
                        expires_ms: r.get(2)?,
                        user: r.get(3)?,
                        role: Role::parse(&role).ok_or_else(|| {
                            StoreError::Corrupt(format!("a session of role {role:?}"))
                        })?,
                    })
                },
            )
            .optional()
    }

    /// Ends a session (logout).
    pub fn delete_session(&self, id: &str) -> Result<()> {
        self.conn()?
            .execute("DELETE FROM sessions WHERE id = ?1", params![id])?;
        Ok(())
    }
}
