"""Validates deploy/kubernetes/ offline: every manifest against the
Kubernetes JSON schemas bundled by kubernetes-validate (strict: unknown
fields are errors), and the facts that tie the manifests to the image and
the server (ports, probe paths, grace period vs. the server's drain, label
selectors, the Indexed Job's shard count).

Usage: validate_kubernetes.py DEPLOY_DIR DOCKERFILE KUBERNETES_VERSION
Prints one line per check; exit status 1 on any failure.
"""

import copy
import glob
import os
import re
import sys

import kubernetes_validate
import yaml

failures = []


def check(condition, what):
    print(("ok   " if condition else "FAIL ") + what)
    if not condition:
        failures.append(what)


def main():
    deploy, dockerfile, version = sys.argv[1:4]
    docs = {}
    for path in sorted(glob.glob(os.path.join(deploy, "*.yaml"))):
        with open(path) as f:
            for doc in yaml.safe_load_all(f):
                docs.setdefault(doc["kind"], []).append((os.path.basename(path), doc))

    # Every resource against the schemas of this Kubernetes version.
    for kind, items in docs.items():
        for name, doc in items:
            if kind == "Kustomization":
                for resource in doc["resources"]:
                    check(os.path.exists(os.path.join(deploy, resource)), f"{name}: lists {resource}")
                continue
            try:
                kubernetes_validate.validate(doc, version, strict=True)
                check(True, f"{name}: {kind} valid against Kubernetes {version} (strict)")
            except kubernetes_validate.ValidationError as e:
                check(False, f"{name}: {kind}: {e.message} at {list(e.path)}")

    # The validator is not a rubber stamp: a typo'd field must fail.
    deployment = docs["Deployment"][0][1]
    broken = copy.deepcopy(deployment)
    broken["spec"]["template"]["spec"]["containers"][0]["readinessProbes"] = {}
    try:
        kubernetes_validate.validate(broken, version, strict=True)
        check(False, "a misspelt field is rejected")
    except kubernetes_validate.ValidationError:
        check(True, "a misspelt field is rejected")

    # Facts that tie the manifests to the Dockerfile and the server.
    text = open(dockerfile).read()
    bind = re.search(r"^ENV TREEMANIP_BIND=\S+:(\d+)$", text, re.M)
    user = re.search(r"^USER (\d+)$", text, re.M)
    pod = deployment["spec"]["template"]["spec"]
    server = pod["containers"][0]
    port = server["ports"][0]["containerPort"]
    check(bind is not None and int(bind.group(1)) == port, f"container port {port} is the image's TREEMANIP_BIND port")
    check(user is not None and pod["securityContext"]["runAsUser"] == int(user.group(1)), "runs as the image's non-root user")
    check(server["readinessProbe"]["httpGet"]["path"] == "/readyz", "readiness on /readyz")
    check(server["livenessProbe"]["httpGet"]["path"] == "/healthz", "liveness on /healthz")
    env = {e["name"]: e["value"] for e in server.get("env", [])}
    timeout = float(env.get("TREEMANIP_REQUEST_TIMEOUT", "10"))
    drain = timeout + 5  # the server's drain: request timeout + 5 s
    pre_stop = float(server["lifecycle"]["preStop"]["exec"]["command"][1])
    grace = pod["terminationGracePeriodSeconds"]
    check(grace >= pre_stop + drain, f"grace {grace} s covers preStop {pre_stop} s + drain {drain} s")
    limits, requests = server["resources"]["limits"], server["resources"]["requests"]
    check("memory" in limits and "cpu" in requests, "CPU request and memory limit set")
    labels = deployment["spec"]["template"]["metadata"]["labels"]

    def selects(selector):
        return all(labels.get(k) == v for k, v in selector.items())

    check(selects(docs["Service"][0][1]["spec"]["selector"]), "the Service selects the server pods")
    check(selects(docs["PodDisruptionBudget"][0][1]["spec"]["selector"]["matchLabels"]), "the PDB selects the server pods")
    hpa = docs["HorizontalPodAutoscaler"][0][1]["spec"]
    check(hpa["scaleTargetRef"]["name"] == deployment["metadata"]["name"], "the HPA scales the Deployment")
    check(hpa["minReplicas"] >= 2, "the HPA keeps at least 2 replicas (with the PDB, one can go)")
    jobs = {doc["metadata"]["name"]: doc for _, doc in docs["Job"]}
    collect = jobs["treemanip-dataset"]["spec"]
    args = collect["template"]["spec"]["containers"][0]["args"]
    check(collect["completionMode"] == "Indexed", "the dataset Job is Indexed")
    shards = int(args[args.index("--shards") + 1])
    check(shards == collect["completions"], f"--shards {shards} equals the Job's completions")
    merge = jobs["treemanip-dataset-merge"]["spec"]["template"]["spec"]["containers"][0]["args"]
    check(merge[:2] == ["dataset", "merge"], "the merge Job runs dataset merge")
    volume = lambda spec: spec["template"]["spec"]["volumes"][0]["persistentVolumeClaim"]["claimName"]
    check(volume(collect) == volume(jobs["treemanip-dataset-merge"]["spec"]) == docs["PersistentVolumeClaim"][0][1]["metadata"]["name"], "shards and merge share the claim")
    if failures:
        print(f"{len(failures)} checks failed", file=sys.stderr)
        sys.exit(1)
    print("all kubernetes checks passed")


if __name__ == "__main__":
    main()
