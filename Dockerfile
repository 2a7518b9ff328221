# The mocomp command line in an image, for RD studies on a cluster
# (examples/k8s/rd-job.yaml). Build from the repository root:
#   docker build -t mocomp .
# The binary is built from this checkout with the locked dependencies;
# plots need no system font (DejaVu is compiled in).
FROM rust:1-slim-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked --bin mocomp

FROM debian:bookworm-slim
COPY --from=build /src/target/release/mocomp /usr/local/bin/mocomp
WORKDIR /data
CMD ["mocomp", "--help"]
