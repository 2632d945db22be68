# The HTTP service (`treemanip serve`, the same as `treemanip-server`) on the
# committed models and native ONNX Runtime; the one `treemanip` binary also
# runs the CLI's batch work (e.g. the sharded dataset Job). It is built
# without the trainer (`--no-default-features`: no burn, no tract), so the
# image compiles only the server's crates and the burn-free commands.
#   docker build -t treemanip .            (or: podman build --format docker -t treemanip .)
#   docker run -p 8080:8080 treemanip
# scripts/container-test builds and runs this file for real with podman,
# making the three base images locally when no registry can be reached.

# 1. The release binary (stripped). ONNX Runtime comes from stage 2, so the
#    binary need not embed its own copy.
FROM docker.io/library/rust:1.95-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY scripts/fetch-onnxruntime scripts/fetch-onnxruntime
COPY crates crates
COPY src src
COPY benches benches
COPY assets assets
ENV TREEMANIP_EMBED_ORT=0 CARGO_PROFILE_RELEASE_STRIP=true
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p treemanip --no-default-features --bin treemanip \
 && mkdir -p /out \
 && cp target/release/treemanip /out/

# 2. ONNX Runtime's shared library from PyPI's onnxruntime wheel.
FROM docker.io/library/python:3.11-slim AS onnxruntime
COPY scripts/fetch-onnxruntime /usr/local/bin/fetch-onnxruntime
RUN fetch-onnxruntime /opt/onnxruntime

# 3. Runtime: Debian slim (glibc, libstdc++) and our files; no toolchain, no
#    shell tools added. The health check is the binary itself.
FROM docker.io/library/debian:bookworm-slim
RUN useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin treemanip
COPY --from=build /out/treemanip /usr/local/bin/treemanip
COPY --from=onnxruntime /opt/onnxruntime/libonnxruntime.so.1.31.1 /opt/onnxruntime/libonnxruntime.so.1.31.1
COPY models/*.onnx /app/models/
# The shipped arms (self-contained imported descriptions), served by name
# beside the built-in ur5.
COPY robots/*.toml /app/robots/
ENV ORT_DYLIB_PATH=/opt/onnxruntime/libonnxruntime.so.1.31.1
ENV TREEMANIP_MODELS_DIR=/app/models
ENV TREEMANIP_ROBOTS_DIR=/app/robots
ENV TREEMANIP_BIND=0.0.0.0:8080
ENV TREEMANIP_LOG_FORMAT=json
USER 10001
WORKDIR /tmp
EXPOSE 8080
STOPSIGNAL SIGTERM
HEALTHCHECK --interval=10s --timeout=3s --start-period=5s --retries=3 CMD ["/usr/local/bin/treemanip", "serve", "--health-check"]
ENTRYPOINT ["/usr/local/bin/treemanip", "serve"]
