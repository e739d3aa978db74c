//! Users and their tokens (admins only): `GET /v1/users`, `POST /v1/users` (the new token is
//! in the answer, once) and `DELETE /v1/users/{name}` (revokes it at once).

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;

use super::auth::{ADMIN, WORKERS};
use super::{App, AppError, AppResult, now_ms, random_token};
use crate::protocol::{AddedUser, ErrorBody, NewUser, User, check_user_name};

/// Every user, revoked ones too.
#[utoipa::path(get, path = "/v1/users", tag = "clients",
    responses((status = 200, body = Vec<User>), (status = 403, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn list_users(State(app): State<Arc<App>>) -> AppResult<Json<Vec<User>>> {
    Ok(Json(app.store.users()?))
}

/// Add a user (or a worker) with a token of its own; the token is shown only in this answer.
#[utoipa::path(post, path = "/v1/users", tag = "clients", request_body = NewUser,
    responses((status = 201, body = AddedUser), (status = 400, body = ErrorBody), (status = 403, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn add_user(
    State(app): State<Arc<App>>,
    body: Result<Json<NewUser>, JsonRejection>,
) -> AppResult<(StatusCode, Json<AddedUser>)> {
    let Json(new) = body?;
    check_user_name(&new.name).map_err(AppError::bad_request)?;
    if new.name == ADMIN || new.name == WORKERS {
        return Err(AppError::bad_request(format!(
            "name: \"{}\" is the coordinator's own token's; choose another",
            new.name
        )));
    }
    let token = random_token()?;
    let now = now_ms();
    if !app
        .store
        .add_user(&new.name, new.role, &crate::store::token_hash(&token), now)?
    {
        return Err(AppError::conflict(format!(
            "user {} exists: revoke it first (DELETE /v1/users/{})",
            new.name, new.name
        )));
    }
    tracing::info!(user = %new.name, role = new.role.as_str(), "user added");
    let user = User {
        name: new.name,
        role: new.role,
        created_ms: now,
        revoked_ms: None,
    };
    Ok((StatusCode::CREATED, Json(AddedUser { user, token })))
}

/// Revoke a user's token: refused from now on, its dashboard sessions ended.
#[utoipa::path(delete, path = "/v1/users/{name}", tag = "clients",
    params(("name" = String, Path)),
    responses((status = 200, body = User), (status = 403, body = ErrorBody), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn revoke_user(
    State(app): State<Arc<App>>,
    Path(name): Path<String>,
) -> AppResult<Json<User>> {
    if !app.store.revoke_user(&name, now_ms())? {
        return Err(AppError::not_found(format!(
            "no user {name} with a live token"
        )));
    }
    tracing::info!(user = %name, "user revoked");
    app.store
        .users()?
        .into_iter()
        .find(|u| u.name == name)
        .map(Json)
        .ok_or_else(|| AppError::internal("a revoked user vanished"))
}
