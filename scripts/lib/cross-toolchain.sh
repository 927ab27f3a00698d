# Shared by the scripts that cross-build for thumbv7em-none-eabihf (sourced, not run).
# The same two routes as scripts/fw-build (see /work/shared/TOOLCHAIN.md):
#   rustup: the rustup target is installed -> plain `cargo build --target`;
#   debian: Debian's rustc 1.96 + std sources with `-Zbuild-std=core`, in its own target dir,
#           the Debian packages installed when missing.
# After `cross_select_route`, `cross_cargo_build ARGS...` builds and `$CROSS_ROUTE` /
# `$CROSS_TARGET_SUBDIR` say which route and target-dir suffix were chosen.
# Environment: FW_ROUTE=rustup|debian forces a route (the name fw-build uses).

CROSS_TARGET=thumbv7em-none-eabihf
CROSS_DEBIAN_PACKAGES=(rustc-web cargo-web rust-web-src lld-22 binutils-arm-none-eabi)

cross_log() { printf '%s: %s\n' "${CROSS_LOG_NAME:-cross}" "$*" >&2; }

cross_have_rustup_target() {
    command -v rustup >/dev/null 2>&1 &&
        rustup target list --installed 2>/dev/null | grep -qx "$CROSS_TARGET"
}

# Runs a command as root: directly when we are root, through sudo when it exists.
cross_as_root() {
    if [ "$(id -u)" -eq 0 ]; then
        "$@"
    elif command -v sudo >/dev/null 2>&1; then
        sudo "$@"
    else
        cross_log "need root to run: $* (no sudo available)"
        exit 1
    fi
}

# Installs the named Debian packages that are not installed yet.
cross_ensure_packages() {
    local missing=()
    for pkg in "$@"; do
        dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' ||
            missing+=("$pkg")
    done
    if [ "${#missing[@]}" -gt 0 ]; then
        cross_log "installing ${missing[*]}"
        cross_as_root apt-get update
        cross_as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
    fi
}

cross_select_route() {
    CROSS_ROUTE=${FW_ROUTE:-}
    if [ -z "$CROSS_ROUTE" ]; then
        if cross_have_rustup_target; then CROSS_ROUTE=rustup; else CROSS_ROUTE=debian; fi
    fi
    case "$CROSS_ROUTE" in
        rustup) CROSS_TARGET_SUBDIR=rustup ;;
        debian)
            cross_ensure_packages "${CROSS_DEBIAN_PACKAGES[@]}"
            for tool in /usr/bin/rustc /usr/bin/cargo /usr/bin/rust-lld; do
                [ -x "$tool" ] || { cross_log "$tool missing after install"; exit 1; }
            done
            CROSS_TARGET_SUBDIR=debian
            ;;
        *) cross_log "FW_ROUTE must be rustup or debian, not '$CROSS_ROUTE'"; exit 2 ;;
    esac
}

# Both routes build the same code with the same profile (Cargo.toml) for rustc's built-in
# thumbv7em-none-eabihf target; the Debian route's only difference is that it compiles core
# itself (`-Zbuild-std=core`, which needs RUSTC_BOOTSTRAP=1) because it has no prebuilt one.
cross_cargo_build() {
    if [ "$CROSS_ROUTE" = rustup ]; then
        cargo build --release --target "$CROSS_TARGET" "$@"
    else
        # -Zbuild-std belongs on the command line, never in .cargo/config.toml [unstable]:
        # with RUSTC_BOOTSTRAP=1 that would break host builds (TOOLCHAIN.md).
        RUSTC=/usr/bin/rustc RUSTDOC=/usr/bin/rustdoc RUSTC_BOOTSTRAP=1 \
            /usr/bin/cargo build --release -Zbuild-std=core --target "$CROSS_TARGET" "$@"
    fi
}
