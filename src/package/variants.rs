//! The prebuilt variants of the FMU binary (fmu/): each carries one set of
//! kinds and contact laws and one FMI standard (Cargo features of the same
//! names), and a scene is packaged with the smallest variant that covers
//! it. `beamstop variants` lists them for `scripts/build-variants`, which
//! builds each into `target/variants/<name>/`.

use std::path::{Path, PathBuf};

use crate::component::Component;

use super::FmiVersion;

/// A set of kinds and laws one prebuilt binary carries (for either standard).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variant {
    pub name: &'static str,
    pub kinds: &'static [&'static str],
    /// Law names as scenes write them (`"type"`); see [`crate::contact::LAWS`].
    pub laws: &'static [&'static str],
}

/// Every variant, smallest first: the packager takes the first that covers
/// a scene. `modal` covers any modal scene (several laws at once).
pub const VARIANTS: [Variant; 5] = [
    Variant { name: "rigid", kinds: &["modal"], laws: &["restitution"] },
    Variant { name: "spring", kinds: &["modal"], laws: &["spring_dashpot"] },
    Variant { name: "compliant", kinds: &["modal"], laws: &["hertz", "power_law"] },
    Variant { name: "modal", kinds: &["modal"], laws: &["restitution", "spring_dashpot", "hertz", "power_law"] },
    // A rotating beam's surface takes any compliant law.
    Variant { name: "rotating", kinds: &["rotating"], laws: &["spring_dashpot", "hertz", "power_law"] },
];

impl Variant {
    /// The Cargo features of fmu/ that build this variant for `version`.
    pub fn features(&self, version: FmiVersion) -> Vec<&'static str> {
        let mut features: Vec<&'static str> = self.kinds.to_vec();
        for law in self.laws {
            let feature = law_feature(law);
            if !features.contains(&feature) {
                features.push(feature);
            }
        }
        features.push(standard_feature(version));
        features
    }

    /// Whether this variant carries every part a scene of `kind` with
    /// `laws` needs.
    pub fn covers(&self, kind: &str, laws: &[String]) -> bool {
        self.kinds.contains(&kind) && laws.iter().all(|l| self.laws.contains(&l.as_str()))
    }

    /// The directory name of its build for `version`.
    pub fn build_name(&self, version: FmiVersion) -> String {
        format!("{}-{}", self.name, standard_feature(version))
    }

    /// What the binary contains, by part, for documentation:
    /// `[(part, names)]`.
    pub fn contents(&self, version: FmiVersion) -> Vec<(&'static str, Vec<&'static str>)> {
        let mut solvers = Vec::new();
        if self.kinds.contains(&"modal") {
            solvers.push("closed form (free flight, held and spring-contact phases)");
            if self.laws.iter().any(|l| law_feature(l) == "power-law") {
                solvers.push("force collocation (Hertz and power-law contact phases)");
            }
        }
        if self.kinds.contains(&"rotating") {
            solvers.extend(["exponential integrator", "DOP853", "Radau IIA"]);
        }
        vec![
            ("variant", vec![self.name]),
            ("kinds", self.kinds.to_vec()),
            ("contact laws", self.laws.to_vec()),
            ("solvers", solvers),
            ("FMI standard", vec![version.number()]),
        ]
    }
}

/// The feature of fmu/ (and beamstop) that carries a law.
pub fn law_feature(law: &str) -> &'static str {
    match law {
        "restitution" => "restitution",
        "spring_dashpot" => "spring-dashpot",
        _ => "power-law",
    }
}

fn standard_feature(version: FmiVersion) -> &'static str {
    match version {
        FmiVersion::Fmi2 => "fmi2",
        FmiVersion::Fmi3 => "fmi3",
    }
}

/// The kind and the law names of a scene.
pub fn parts(scene: &Component) -> (&'static str, Vec<String>) {
    let laws = crate::contact::laws_in(&serde_json::from_str(&scene.canonical_json()).expect("a canonical scene is JSON"));
    (scene.kind().name(), laws.into_iter().map(|(name, _)| name).collect())
}

/// The smallest variant that covers `scene`; an error naming its kind and
/// laws when none does.
pub fn covering(scene: &Component) -> Result<&'static Variant, String> {
    let (kind, laws) = parts(scene);
    VARIANTS.iter().find(|v| v.covers(kind, &laws)).ok_or_else(|| {
        format!("scene '{}': no prebuilt FMU binary carries the {kind} kind with the laws {}", scene.name(), laws.join(", "))
    })
}

/// Where `scripts/build-variants` puts the variants: `target/variants`,
/// beside the `target/<profile>` of the running executable.
pub fn variants_dir() -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let profile_dir = exe.parent().ok_or("no executable directory")?;
    let target = profile_dir.parent().ok_or("no target directory")?;
    Ok(target.join("variants"))
}

/// The stripped binary of `variant` for `version` under `dir`; an error
/// saying how to build it when it is missing.
pub fn binary(dir: &Path, variant: &Variant, version: FmiVersion) -> Result<PathBuf, String> {
    let path = dir.join(variant.build_name(version)).join(format!("{}beamstop_fmu{}", std::env::consts::DLL_PREFIX, std::env::consts::DLL_SUFFIX));
    if path.exists() {
        Ok(path)
    } else {
        Err(format!("the FMU binary variant {} is not built ({} is missing): run scripts/build-variants", variant.build_name(version), path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_law_and_kind_is_in_a_variant_and_the_modal_variant_covers_every_modal_law() {
        for (law, _) in crate::contact::LAWS {
            assert!(VARIANTS.iter().any(|v| v.laws.contains(&law)), "{law}");
        }
        for (kind, _) in crate::kinds::KINDS {
            assert!(VARIANTS.iter().any(|v| v.kinds.contains(&kind)), "{kind}");
        }
        let all: Vec<String> = crate::contact::LAWS.iter().map(|(l, _)| l.to_string()).collect();
        assert!(VARIANTS.iter().find(|v| v.name == "modal").unwrap().covers("modal", &all));
        assert_eq!(VARIANTS[0].features(FmiVersion::Fmi2), ["modal", "restitution", "fmi2"]);
        assert_eq!(VARIANTS[4].features(FmiVersion::Fmi3), ["rotating", "spring-dashpot", "power-law", "fmi3"]);
    }
}
