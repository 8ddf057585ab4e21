#pragma once
/// \file The engine's version and the commit it was built from.

namespace mpm {

/// `git describe --always --dirty` of the source tree at build time ("unknown" outside git).
const char* git_commit();

}  // namespace mpm
