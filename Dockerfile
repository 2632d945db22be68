# treemanip-server with the committed models on native ONNX Runtime.
#   docker build -t treemanip .
#   docker run -p 8080:8080 treemanip
# scripts/container-smoke checks the runtime stage's layout without Docker.

# 1. The release binary.
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock build.rs openapi.yaml ./
COPY scripts/fetch-onnxruntime scripts/fetch-onnxruntime
COPY src src
COPY benches benches
COPY assets assets
# The runtime stage loads ONNX Runtime from ORT_DYLIB_PATH, so the binary
# need not carry its own copy.
ENV TREEMANIP_EMBED_ORT=0
RUN cargo build --release --locked --bin treemanip-server

# 2. ONNX Runtime's shared library from PyPI's onnxruntime wheel.
FROM python:3.11-slim AS onnxruntime
COPY scripts/fetch-onnxruntime /usr/local/bin/fetch-onnxruntime
RUN fetch-onnxruntime /opt/onnxruntime

# 3. Runtime: glibc, libstdc++, curl for the health check; no toolchain.
FROM debian:bookworm-slim
RUN apt-get update \
 && apt-get install -y --no-install-recommends ca-certificates curl libstdc++6 \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin treemanip
COPY --from=build /src/target/release/treemanip-server /usr/local/bin/treemanip-server
COPY --from=onnxruntime /opt/onnxruntime/libonnxruntime.so.1.31.1 /opt/onnxruntime/libonnxruntime.so.1.31.1
COPY models /app/models
ENV ORT_DYLIB_PATH=/opt/onnxruntime/libonnxruntime.so.1.31.1
ENV TREEMANIP_MODELS_DIR=/app/models
ENV TREEMANIP_BIND=0.0.0.0:8080
ENV TREEMANIP_LOG_FORMAT=json
USER 10001
EXPOSE 8080
HEALTHCHECK --interval=30s --timeout=3s --start-period=10s CMD curl -fsS http://127.0.0.1:8080/healthz || exit 1
ENTRYPOINT ["/usr/local/bin/treemanip-server"]
