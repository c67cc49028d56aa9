# The Rust builder base: a Debian base, a C toolchain for linking (and ring's C parts), and a
# Rust toolchain copied in by deploy/base/build-bases. Any image with rustc >= the workspace's
# rust-version, cargo, gcc and libc6-dev serves as the deploy Dockerfile's BUILDER_IMAGE.
ARG BASE_IMAGE
FROM ${BASE_IMAGE}
RUN apt-get update \
 && apt-get install -y --no-install-recommends gcc libc6-dev ca-certificates \
 && rm -rf /var/lib/apt/lists/*
COPY rust /usr/local/rust
# The builder host's extra certificate authorities (a TLS-inspecting proxy between the
# builder and crates.io), so that cargo trusts what the host trusts.
COPY ca/ /usr/local/share/ca-certificates/
RUN update-ca-certificates
ENV PATH=/usr/local/rust/bin:$PATH \
    CARGO_HOME=/usr/local/cargo
