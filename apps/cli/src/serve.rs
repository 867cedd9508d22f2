//! `strata serve`: the collaboration server (see `strata-server`).

use std::io::Write as _;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};
use strata_server::{PgStorage, RedbStorage, Server, ServerConfig, Storage};

/// The storage `store` names: a `postgres://` (or `postgresql://`) URL, or a redb file.
pub fn storage(store: &str) -> Result<Arc<dyn Storage>> {
    if store.starts_with("postgres://") || store.starts_with("postgresql://") {
        let pg = PgStorage::open(store).with_context(|| "cannot use the PostgreSQL database".to_owned())?;
        Ok(Arc::new(pg))
    } else {
        let path = Path::new(store);
        let redb = RedbStorage::open(path).with_context(|| format!("cannot open the room store {}", path.display()))?;
        Ok(Arc::new(redb))
    }
}

/// Serves rooms on `listen`, kept in `store`, until the process is stopped. The first line on
/// standard output says where it listens (`strata: serving rooms on ws://…`).
pub fn serve(listen: &str, store: &str) -> Result<String> {
    let storage = storage(store)?;
    let server = Server::start(listen, storage, ServerConfig::default())
        .with_context(|| format!("cannot listen on {listen}"))?;
    println!("strata: serving rooms on {} (store: {store})", server.url());
    std::io::stdout().flush()?;
    server.wait();
    Ok(String::new())
}
