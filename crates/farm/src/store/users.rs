//! Users and their tokens: each token is kept as its SHA-256 only, with the user's name and
//! role; a revoked token stays listed (who it was, since when) and is refused.

use super::db::{Optional, params};
use super::{Result, Store, StoreError};
use crate::protocol::{Role, User};

/// The hash a token is kept and looked up by.
pub fn token_hash(token: &str) -> String {
    crate::bundle::hash(token.as_bytes())
}

fn role_of(name: &str, s: String) -> Result<Role> {
    Role::parse(&s).ok_or_else(|| StoreError::Corrupt(format!("user {name} has no role {s:?}")))
}

impl Store {
    /// Adds a user with the token whose hash is `token_hash`. A name in use by a user whose
    /// token is not revoked is refused (false); a revoked one's name is taken over.
    pub fn add_user(&self, name: &str, role: Role, token_hash: &str, now: i64) -> Result<bool> {
        self.db.write(|tx| {
            let live: Option<i64> = tx
                .query_row(
                    "SELECT 1 FROM users WHERE name = ?1 AND revoked_ms IS NULL",
                    params![name],
                    |r| r.get(0),
                )
                .optional()?;
            if live.is_some() {
                return Ok(false);
            }
            tx.execute("DELETE FROM users WHERE name = ?1", params![name])?;
            tx.execute(
                "INSERT INTO users (name, role, token_hash, created_ms) VALUES (?1, ?2, ?3, ?4)",
                params![name, role.as_str(), token_hash, now],
            )?;
            Ok(true)
        })
    }

    /// Every user, by name.
    pub fn users(&self) -> Result<Vec<User>> {
        self.conn()?.query_map(
            "SELECT name, role, created_ms, revoked_ms FROM users ORDER BY name",
            params![],
            |r| {
                let name: String = r.get(0)?;
                Ok(User {
                    role: role_of(&name, r.get(1)?)?,
                    name,
                    created_ms: r.get(2)?,
                    revoked_ms: r.get(3)?,
                })
            },
        )
    }

    /// Revokes a user's token; false if no user of that name holds a live one.
    pub fn revoke_user(&self, name: &str, now: i64) -> Result<bool> {
        let n = self.conn()?.execute(
            "UPDATE users SET revoked_ms = ?2 WHERE name = ?1 AND revoked_ms IS NULL",
            params![name, now],
        )?;
        Ok(n > 0)
    }

    /// The user a live token (by its hash) belongs to: (name, role).
    pub fn user_of_token(&self, token_hash: &str) -> Result<Option<(String, Role)>> {
        let row: Option<(String, String)> = self
            .conn()?
            .query_row(
                "SELECT name, role FROM users WHERE token_hash = ?1 AND revoked_ms IS NULL",
                params![token_hash],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()?;
        Ok(match row {
            Some((name, role)) => Role::parse(&role).map(|r| (name, r)),
            None => None,
        })
    }

    /// Who submitted job `id`: None if there is no such job, `Some(None)` for a job of no
    /// known submitter.
    pub fn job_submitter(&self, id: i64) -> Result<Option<Option<String>>> {
        self.conn()?
            .query_row(
                "SELECT submitter FROM jobs WHERE id = ?1",
                params![id],
                |r| r.get::<Option<String>>(0),
            )
            .optional()
    }

    /// The name a worker (by its process id) registered under.
    pub fn worker_name(&self, id: &str) -> Result<Option<String>> {
        Ok(self
            .conn()?
            .query_row("SELECT name FROM workers WHERE id = ?1", params![id], |r| {
                r.get(0)
            })
            .optional()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_revoked_token_is_refused_and_its_name_can_be_given_again() {
        let dir = tempfile::tempdir().expect("dir");
        let store = crate::store::tests::open_test(dir.path());
        assert!(
            store
                .add_user("ana", Role::Artist, &token_hash("t1"), 1)
                .expect("add")
        );
        assert!(
            !store
                .add_user("ana", Role::Viewer, &token_hash("t2"), 2)
                .expect("add")
        );
        assert_eq!(
            store.user_of_token(&token_hash("t1")).expect("lookup"),
            Some(("ana".into(), Role::Artist))
        );
        assert_eq!(
            store.user_of_token(&token_hash("t2")).expect("lookup"),
            None
        );
        assert!(store.revoke_user("ana", 3).expect("revoke"));
        assert!(!store.revoke_user("ana", 4).expect("revoke"));
        assert_eq!(
            store.user_of_token(&token_hash("t1")).expect("lookup"),
            None
        );
        let users = store.users().expect("list");
        assert_eq!(users.len(), 1);
        assert_eq!(users[0].revoked_ms, Some(3));
        assert!(
            store
                .add_user("ana", Role::Viewer, &token_hash("t3"), 5)
                .expect("add")
        );
        assert_eq!(
            store.user_of_token(&token_hash("t3")).expect("lookup"),
            Some(("ana".into(), Role::Viewer))
        );
    }

    #[test]
    fn coordinators_starting_together_agree_on_a_new_object_store_id() {
        let dir = tempfile::tempdir().expect("dir");
        let store = crate::store::tests::open_test(dir.path());
        let first = store.adopt_objects("aaaa", "s3://b/farm").expect("adopt");
        let second = store.adopt_objects("bbbb", "s3://b/farm").expect("adopt");
        assert_eq!((first.as_str(), second.as_str()), ("aaaa", "aaaa"));
        // Another store (another location) is not given this one's id: the check refuses it.
        let other = store
            .adopt_objects("cccc", "/srv/elsewhere")
            .expect("adopt");
        assert_eq!(other, "cccc");
        assert!(
            store
                .check_objects("aaaa", "s3://b/farm")
                .expect("check")
                .is_none()
        );
        assert!(
            store
                .check_objects(&other, "/srv/elsewhere")
                .expect("check")
                .is_some()
        );
    }
}
