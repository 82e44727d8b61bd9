// The one translation unit that compiles the vendored mcap library's implementation (reader,
// writer, zstd and lz4 chunk compression). The library's public symbols are exported from
// rgbdt_bag, so tests can write MCAP files with mcap::McapWriter through the headers alone.
#define MCAP_IMPLEMENTATION
#include <mcap/mcap.hpp>
