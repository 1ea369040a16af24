//! `planner keygen`: an Ed25519 key pair for signed answers.

use anyhow::{Context, Result};
use protocol::ResponseSigner;

/// Writes a new key pair: `out` (secret seed, 0600) and `out.pub`.
pub fn run(out: &std::path::Path) -> Result<()> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let mut seed = [0u8; protocol::KEY_LENGTH];
    getrandom::fill(&mut seed).map_err(|e| anyhow::anyhow!("the system's random source: {e}"))?;
    let signer = ResponseSigner::from_seed(&seed);
    let public = out.with_extension(match out.extension() {
        Some(ext) => format!("{}.pub", ext.to_string_lossy()),
        None => "pub".into(),
    });
    let write = |path: &std::path::Path, text: String, mode: u32| -> Result<()> {
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(mode)
            .open(path)
            .with_context(|| format!("creating {}", path.display()))?;
        file.write_all(format!("{text}\n").as_bytes())
            .with_context(|| format!("writing {}", path.display()))
    };
    // Neither file may exist: never half a pair, never a key vehicles already trust replaced.
    if let Some(existing) = [out, public.as_path()].into_iter().find(|p| p.exists()) {
        anyhow::bail!("{} exists: not overwritten", existing.display());
    }
    write(out, signer.seed_hex(), 0o600)?;
    write(&public, signer.verifier().to_hex(), 0o644)?;
    println!(
        "secret key: {}\npublic key: {} ({})",
        out.display(),
        public.display(),
        signer.verifier().to_hex()
    );
    Ok(())
}
