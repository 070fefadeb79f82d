//! The deployment files agree with each other and with Kubernetes: the manifests in
//! `deploy/k8s/` pass the offline schema validator `kubernetes-validate --strict` (CI
//! installs it; without it that test prints a SKIPPED line), and the fork lists that the
//! host is given name exactly the forks the StatefulSet and the compose file start.

use magg_tests::docker::output;
use magg_tests::workspace_root;
use std::path::PathBuf;
use std::process::Command;

fn manifests() -> Vec<PathBuf> {
    let dir = workspace_root().join("deploy/k8s");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    files.sort();
    files
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(workspace_root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The value of the first `key: value` line after the line containing `after`.
fn value_after(text: &str, after: &str, key: &str) -> String {
    let rest = &text[text.find(after).unwrap_or_else(|| panic!("no {after:?}"))..];
    let line =
        rest.lines().find(|l| l.trim_start().starts_with(key)).unwrap_or_else(|| panic!("no {key} after {after:?}"));
    line.trim_start()[key.len()..].trim().trim_matches('"').to_string()
}

#[test]
fn kubernetes_manifests_pass_the_offline_schema_validator() {
    let files = manifests();
    assert!(files.len() >= 3, "deploy/k8s has {} manifests", files.len());
    if let Err(e) = output(Command::new("kubernetes-validate").arg("--version")) {
        magg_tests::docker::skipped(&format!(
            "kubernetes-validate is not installed (pip install kubernetes-validate): {}; \
             kubernetes_manifests_pass_the_offline_schema_validator did not run",
            e.lines().next().unwrap_or("")
        ));
        return;
    }
    let result = output(Command::new("kubernetes-validate").args(["--strict", "--quiet"]).args(&files));
    if let Err(e) = result {
        panic!("deploy/k8s does not validate:\n{e}");
    }
}

#[test]
fn the_host_is_given_exactly_the_forks_that_are_started() {
    // Kubernetes: StatefulSet magg-fork with N replicas -> magg-fork-0 .. N-1 via the
    // headless Service magg-fork.
    let forks = read("deploy/k8s/forks.yaml");
    let replicas: usize = value_after(&forks, "kind: StatefulSet", "replicas:").parse().unwrap();
    assert_eq!(value_after(&forks, "kind: StatefulSet", "serviceName:"), "magg-fork");
    let job = read("deploy/k8s/render-job.yaml");
    let listed = value_after(&job, "name: MAGG_FORKS_AT", "value:");
    let expected: Vec<String> = (0..replicas).map(|i| format!("magg-fork-{i}.magg-fork:7100")).collect();
    assert_eq!(listed.split(',').collect::<Vec<_>>(), expected, "render-job.yaml MAGG_FORKS_AT");
    // Images come from no registry.
    for f in manifests() {
        let text = std::fs::read_to_string(&f).unwrap();
        let images = text.matches("image: magg-").count();
        let never = text.matches("imagePullPolicy: Never").count();
        assert_eq!(images, never, "{}: every magg image with imagePullPolicy: Never", f.display());
    }

    // Compose: services fork1 .. fork5, the same list in MAGG_FORKS_AT.
    let compose = read("deploy/docker-compose.yml");
    let listed = value_after(&compose, "MAGG_FORKS_AT", "MAGG_FORKS_AT:");
    let forks: Vec<&str> = listed.split(',').collect();
    assert_eq!(forks.len(), 5, "compose MAGG_FORKS_AT: {listed}");
    for (i, f) in forks.iter().enumerate() {
        assert_eq!(*f, format!("fork{}:7100", i + 1));
        assert!(compose.contains(&format!("\n  fork{}: *fork\n", i + 1)), "compose has no service fork{}", i + 1);
    }
    // `docker stack deploy` refuses map-form depends_on and ignores `build:`.
    assert!(!compose.contains("build:"), "docker stack deploy ignores build:");
    assert!(!compose.contains("condition: service_"), "docker stack deploy needs list-form depends_on");
}
