//! Reading `kestrel pipeline`'s TOML configuration into
//! kestrel-tricopter's [`Config`] (one struct per section, every key
//! required, unknown keys rejected, a semantic check that names the key of
//! every bad value). The built-in default is `crates/cli/kestrel.toml`.

use anyhow::Context;
pub use kestrel_tricopter::pipeline::config::*;
use std::path::Path;

/// The committed default configuration (`crates/cli/kestrel.toml`).
pub const DEFAULT_TOML: &str = include_str!("../../kestrel.toml");

/// The built-in default (the committed `kestrel.toml`).
pub fn builtin() -> anyhow::Result<Config> {
    parse(DEFAULT_TOML, "the built-in configuration")
}

/// Reads and checks a configuration file; errors name the file and the key.
pub fn read(path: &Path) -> anyhow::Result<Config> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the configuration {}", path.display()))?;
    parse(&text, &path.display().to_string())
}

/// Parses and checks a configuration; `source` names it in errors.
pub fn parse(text: &str, source: &str) -> anyhow::Result<Config> {
    let cfg: Config = toml::from_str(text).map_err(|e| {
        let key = e.message().to_string();
        anyhow::anyhow!("{source}: {}", e.to_string().trim_end())
            .context(format!("{source}: malformed configuration ({key})"))
    })?;
    cfg.check()
        .with_context(|| format!("{source}: bad value"))?;
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_parses_and_equals_the_committed_file() {
        let a = builtin().unwrap();
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("kestrel.toml");
        let b = read(&path).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.identification.order, 8);
        assert_eq!(a.mpc.larger.blocks, vec![1, 1, 2, 6]);
        let q = a.clone().quick();
        assert_eq!(
            q.identification.pem_max_iterations,
            a.quick.pem_max_iterations
        );
        q.check().unwrap();
    }

    #[test]
    fn unknown_keys_are_rejected_with_their_name() {
        let text = DEFAULT_TOML.replace("order = 8", "order = 8\nordre = 9");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("x.toml") && e.contains("ordre"), "{e}");
    }

    #[test]
    fn wrong_types_and_values_name_the_key() {
        let q2 = "q2 = [0.01, 0.01, 0.01, 0.1]";
        assert!(DEFAULT_TOML.contains(q2));
        let text = DEFAULT_TOML.replace(q2, "q2 = \"small\"");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("x.toml") && e.contains("q2"), "{e}");
        // A diagonal weight of the wrong length, or with a negative entry.
        let text = DEFAULT_TOML.replace(q2, "q2 = [0.01, 0.01, 0.1]");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("mpc.q2") && e.contains("4 numbers"), "{e}");
        let text = DEFAULT_TOML.replace(q2, "q2 = [0.01, -0.01, 0.01, 0.1]");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("mpc.q2"), "{e}");
        // A scalar still works.
        let text = DEFAULT_TOML.replace(q2, "q2 = 0.01");
        let c = parse(&text, "x.toml").unwrap();
        assert_eq!(c.mpc.q2, WeightSpec::Scalar(0.01));
        let text = DEFAULT_TOML.replace("reduced_order = 5", "reduced_order = 9");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("identification.reduced_order"), "{e}");
        let text = DEFAULT_TOML.replace("larger = { horizon = 10", "larger = { horizon = 11");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("mpc.larger"), "{e}");
        let text = DEFAULT_TOML.replace("[firmware]\n", "");
        let e = format!("{:#}", parse(&text, "x.toml").unwrap_err());
        assert!(e.contains("x.toml"), "{e}");
    }
}
