//! The deployment files agree with each other and with Kubernetes: the manifests in
//! `deploy/k8s/` pass the offline schema validator `kubernetes-validate --strict` (CI
//! installs it; without it that test prints a SKIPPED line); every container there has
//! resource requests and limits and runs as a non-root user on a read-only root
//! filesystem; the render Job takes scenes (meshes included) from the host image and
//! writes only its output volume; the fork lists that the host is given name exactly the
//! forks the StatefulSet, the compose file and the stack file start; the compose file
//! waits for health and the stack file is one that `docker stack deploy` takes.

use magg_tests::docker::{output, skipped};
use magg_tests::workspace_root;
use serde_json::Value;
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

/// Every document of every manifest, with its file.
fn documents() -> Vec<(PathBuf, Value)> {
    let mut docs = Vec::new();
    for f in manifests() {
        let text = std::fs::read_to_string(&f).unwrap();
        for d in serde_yaml::Deserializer::from_str(&text) {
            let v: Value = serde::Deserialize::deserialize(d).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            docs.push((f.clone(), v));
        }
    }
    docs
}

/// The pod spec of a workload (a Pod's own spec, or a StatefulSet's, Deployment's or
/// Job's template), with its name.
fn pod_specs() -> Vec<(String, Value)> {
    documents()
        .into_iter()
        .filter_map(|(f, d)| {
            let name = format!("{}: {} {}", f.display(), d["kind"].as_str()?, d["metadata"]["name"].as_str()?);
            let spec = match d["kind"].as_str()? {
                "Pod" => d["spec"].clone(),
                "StatefulSet" | "Deployment" | "Job" => d["spec"]["template"]["spec"].clone(),
                _ => return None,
            };
            Some((name, spec))
        })
        .collect()
}

/// The containers of a pod spec, init containers included.
fn containers(spec: &Value) -> Vec<Value> {
    let list = |key: &str| spec[key].as_array().cloned().unwrap_or_default();
    [list("initContainers"), list("containers")].concat()
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

    // Compose and stack: services fork1 .. fork5, the same list in MAGG_FORKS_AT.
    for file in ["deploy/docker-compose.yml", "deploy/docker-stack.yml"] {
        let text = read(file);
        let listed = value_after(&text, "MAGG_FORKS_AT", "MAGG_FORKS_AT:");
        let forks: Vec<&str> = listed.split(',').collect();
        assert_eq!(forks.len(), 5, "{file} MAGG_FORKS_AT: {listed}");
        for (i, f) in forks.iter().enumerate() {
            assert_eq!(*f, format!("fork{}:7100", i + 1), "{file}");
            assert!(text.contains(&format!("\n  fork{}: *fork\n", i + 1)), "{file} has no service fork{}", i + 1);
        }
        assert!(!text.contains("build:"), "{file}: the images come from deploy/build-images.sh");
    }
}

#[test]
fn compose_waits_for_healthy_forks_and_nodes_and_the_stack_file_has_no_long_depends_on() {
    // Compose: the host starts once every fork and node container is healthy.
    let compose: Value = serde_yaml::from_str(&read("deploy/docker-compose.yml")).unwrap();
    let services = compose["services"].as_object().unwrap();
    let after = compose["services"]["host"]["depends_on"].as_object().expect("host depends_on in the long form");
    for name in ["fork1", "fork2", "fork3", "fork4", "fork5", "node"] {
        assert_eq!(after[name]["condition"], "service_healthy", "compose: the host waits for {name}'s health");
        assert!(services[name]["healthcheck"]["test"].is_array(), "compose: {name} has a healthcheck");
    }
    // Stack: `docker stack deploy` refuses depends_on that is not a list (and a swarm
    // ignores it anyway): none at all.
    let stack: Value = serde_yaml::from_str(&read("deploy/docker-stack.yml")).unwrap();
    for (name, service) in stack["services"].as_object().unwrap() {
        assert!(service.get("depends_on").is_none(), "stack {name}: services.{name}.depends_on must be a list");
    }
    assert_eq!(stack["services"]["host"]["deploy"]["restart_policy"]["condition"], "none");
}

#[test]
fn compose_and_stack_files_are_taken_by_their_tools() {
    // `docker stack config` checks a stack file without a swarm, `config` of a compose
    // client a compose file without an engine. (client, what shows it is there, the check)
    let checks: [(&[&str], &[&str], &[&str]); 3] = [
        (&["docker"], &["stack", "config", "--help"], &["stack", "config", "-c", "deploy/docker-stack.yml"]),
        (&["docker-compose"], &["version"], &["-f", "deploy/docker-compose.yml", "config", "--quiet"]),
        (&["docker", "compose"], &["version"], &["-f", "deploy/docker-compose.yml", "config", "--quiet"]),
    ];
    let mut ran = 0;
    for (client, present, check) in checks {
        let cmd = |args: &[&str]| {
            let mut c = Command::new(client[0]);
            c.current_dir(workspace_root()).args(&client[1..]).args(args);
            c
        };
        if output(&mut cmd(present)).is_err() {
            continue;
        }
        if let Err(e) = output(&mut cmd(check)) {
            panic!("{} {} refuses it:\n{e}", client.join(" "), check.join(" "));
        }
        ran += 1;
    }
    if ran == 0 {
        skipped("no docker stack, docker compose or docker-compose: compose_and_stack_files_are_taken_by_their_tools did not run");
    }
}

#[test]
fn every_container_has_limits_and_runs_unprivileged_on_a_read_only_root() {
    let pods = pod_specs();
    assert!(pods.len() >= 4, "fork, node, render and reader pods: {:?}", pods.iter().map(|p| &p.0).collect::<Vec<_>>());
    for (name, spec) in &pods {
        let pod = &spec["securityContext"];
        assert_eq!(pod["runAsNonRoot"], true, "{name}: pod securityContext.runAsNonRoot");
        assert!(pod["runAsUser"].as_u64().is_some_and(|u| u > 0), "{name}: pod securityContext.runAsUser non-zero");
        let list = containers(spec);
        assert!(!list.is_empty(), "{name}: no containers");
        for c in &list {
            let what = format!("{name} container {}", c["name"]);
            for kind in ["requests", "limits"] {
                for resource in ["cpu", "memory"] {
                    assert!(c["resources"][kind][resource].is_string(), "{what}: resources.{kind}.{resource}");
                }
            }
            let sc = &c["securityContext"];
            assert_eq!(sc["runAsNonRoot"], true, "{what}: securityContext.runAsNonRoot");
            assert_eq!(sc["readOnlyRootFilesystem"], true, "{what}: securityContext.readOnlyRootFilesystem");
            assert_eq!(sc["allowPrivilegeEscalation"], false, "{what}: securityContext.allowPrivilegeEscalation");
            if sc["runAsUser"].is_u64() {
                assert!(sc["runAsUser"].as_u64() > Some(0), "{what}: runAsUser");
            }
        }
    }
    // The images run as the same non-root user (FROM scratch: USER in the Dockerfile).
    let script = read("deploy/build-images.sh");
    assert!(script.contains("user=\"65532:65532\"") && script.contains("USER $user"), "build-images.sh sets USER");
    for (name, spec) in &pods {
        if containers(spec).iter().any(|c| c["image"].as_str().is_some_and(|i| i.starts_with("magg-"))) {
            assert_eq!(spec["securityContext"]["runAsUser"], 65532, "{name}: the images' user");
        }
    }
}

#[test]
fn the_render_job_reads_scenes_with_meshes_from_the_image_and_writes_only_its_volume() {
    let docs = documents();
    let find = |kind: &str, name: &str| {
        docs.iter()
            .map(|(_, d)| d)
            .find(|d| d["kind"] == kind && d["metadata"]["name"] == name)
            .unwrap_or_else(|| panic!("no {kind} {name}"))
            .clone()
    };
    let config = find("ConfigMap", "magg-config");
    // The default scene is one the host image carries at /scenes, meshes and all.
    let scene = config["data"]["scene"].as_str().unwrap();
    let rel = scene.strip_prefix("/scenes/").unwrap_or_else(|| panic!("scene {scene}: not under /scenes"));
    assert!(workspace_root().join("scenes").join(rel).is_file(), "scenes/{rel} is not in the repository");
    assert!(read("deploy/build-images.sh").contains("rootfs/scenes"), "the host image carries the scenes");

    let job = find("Job", "magg-render");
    let spec = &job["spec"]["template"]["spec"];
    let host = &containers(spec)[0];
    let env = host["env"].as_array().unwrap();
    let var = |n: &str| env.iter().find(|e| e["name"] == n).unwrap_or_else(|| panic!("render Job: no {n}")).clone();
    assert_eq!(var("MAGG_MIN_NODES")["valueFrom"]["configMapKeyRef"]["key"], "min-nodes");
    let min: u64 = config["data"]["min-nodes"].as_str().unwrap().parse().unwrap();
    let nodes = find("Deployment", "magg-node")["spec"]["replicas"].as_u64().unwrap();
    assert!((1..=nodes).contains(&min), "min-nodes {min} with {nodes} node replicas");
    assert!(
        host["args"].as_array().unwrap().iter().any(|a| a == "$(MAGG_SCENE)"),
        "the Job renders the configured scene"
    );

    // Writable: the output volume only, and the image is written there.
    for m in host["volumeMounts"].as_array().unwrap() {
        if m["readOnly"] != true {
            assert_eq!(m["mountPath"], "/out", "render Job: writable mount {m}");
        }
    }
    assert!(host["args"].as_array().unwrap().iter().any(|a| a.as_str().is_some_and(|a| a.starts_with("/out/"))));
    let out = spec["volumes"].as_array().unwrap().iter().find(|v| v["name"] == "out").unwrap().clone();
    assert_eq!(out["persistentVolumeClaim"]["claimName"], "magg-out");
    // The volume's group is the pod's, so the non-root host can write there.
    assert_eq!(spec["securityContext"]["fsGroup"], spec["securityContext"]["runAsGroup"]);
    // And a reader pod mounts it to copy the image out (kubectl cp).
    let reader = find("Pod", "magg-out-reader");
    assert_eq!(reader["spec"]["volumes"][0]["persistentVolumeClaim"]["claimName"], "magg-out");
    assert!(read("docs/DEPLOY.md").contains("kubectl cp magg-out-reader:/out/render.png"), "DEPLOY.md says how");
}
