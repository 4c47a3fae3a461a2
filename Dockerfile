# syntax=docker/dockerfile:1
# The `vgps` command line in a slim image: one container per drive, for teams without Python
# (see docs/python.md "Fleet" and deploy/k8s/indexed-job.yaml).
#
#   docker build -t vgps .
#   docker run --rm -v /data:/data vgps replay /data/drives/d1 --out /data/out/d1 --quiet
#
# Stage 1 builds only the binary (the workspace's other members, e.g. the Python crate, are
# resolved but not built); stage 2 is Debian slim (same release as the build image, so the
# same glibc) with the binary and nothing else: the report's fonts, Leaflet and the default
# calibration are compiled into it.
FROM rust:1.95-slim-trixie AS build
WORKDIR /src
COPY . .
# No debugger line tables (as in CI): a faster build, a smaller binary.
ENV CARGO_PROFILE_RELEASE_DEBUG=false
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p vgps --bin vgps \
    && cp target/release/vgps /usr/local/bin/vgps

FROM debian:trixie-slim
COPY --from=build /usr/local/bin/vgps /usr/local/bin/vgps
# Not root: mounted output folders must be writable by uid 1000 (Kubernetes: fsGroup 1000).
RUN useradd --uid 1000 --create-home vgps
USER vgps
ENTRYPOINT ["vgps"]
CMD ["--help"]
