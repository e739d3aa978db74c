//! `tessera users add|list|revoke`: a coordinator's users and their tokens (an admin's token
//! is needed). Roles: admin, artist, viewer, worker (see the route-by-role table in
//! docs/src/farm/roles.md).

use tessera_farm::protocol::{NewUser, Role, User};

use crate::remote::{Remote, duration, table};

#[derive(clap::Args)]
pub struct UsersArgs {
    #[command(subcommand)]
    pub command: UsersCommand,
}

#[derive(clap::Subcommand)]
pub enum UsersCommand {
    /// Add a user (or a worker) and print its token, shown only this once.
    Add {
        /// 1 to 64 letters, digits, '-', '_' or '.'; a worker's is the name it runs under
        /// (`tessera worker --name`).
        name: String,
        /// admin, artist, viewer or worker.
        #[arg(long, value_parser = parse_role)]
        role: Role,
        #[command(flatten)]
        remote: Remote,
    },
    /// List the users, revoked ones too.
    List {
        #[command(flatten)]
        remote: Remote,
        /// JSON, for scripts.
        #[arg(long)]
        json: bool,
    },
    /// Revoke a user's token: refused from now on, its dashboard sessions ended.
    Revoke {
        name: String,
        #[command(flatten)]
        remote: Remote,
    },
}

fn parse_role(s: &str) -> Result<Role, String> {
    Role::parse(s).ok_or_else(|| format!("expected admin, artist, viewer or worker, got \"{s}\""))
}

pub async fn run(args: UsersArgs) -> anyhow::Result<()> {
    match args.command {
        UsersCommand::Add { name, role, remote } => {
            let added = remote.client()?.add_user(&NewUser { name, role }).await?;
            crate::print(&format!(
                "added {} ({}); its token, shown only now:\n{}\n",
                added.user.name,
                added.user.role.as_str(),
                added.token
            ))
        }
        UsersCommand::List { remote, json } => {
            let users = remote.client()?.users().await?;
            if json {
                return crate::print(&(serde_json::to_string_pretty(&users)? + "\n"));
            }
            crate::print(&list(&users, tessera_farm::coordinator::now_ms()))
        }
        UsersCommand::Revoke { name, remote } => {
            let user = remote.client()?.revoke_user(&name).await?;
            crate::print(&format!("revoked {} ({})\n", user.name, user.role.as_str()))
        }
    }
}

fn list(users: &[User], now: i64) -> String {
    let rows = users
        .iter()
        .map(|u| {
            vec![
                u.name.clone(),
                u.role.as_str().into(),
                format!("{} ago", duration(now - u.created_ms)),
                u.revoked_ms
                    .map_or("-".into(), |r| format!("{} ago", duration(now - r))),
            ]
        })
        .collect();
    table(&["USER", "ROLE", "ADDED", "REVOKED"], rows, 0)
}
