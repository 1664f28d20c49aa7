// Instruction counts per CSV row on Linux targets (scripts/insn_count.sh, docs/target.md "Linux bench
// controller"): read_record_csv of one file, on the vector cell path (`cells`, SSSE3 on x86-64,
// Advanced SIMD on AArch64) or the scalar path every architecture has (`scalar`), one thread. The
// counts of two files that differ only in their number of rows differ by the instructions of those
// rows: start-up and set-up cancel.
//   usage: msid_insn_csv cells|scalar FILE
#include "msid_records.hpp"

#include <cstdio>
#include <cstring>
#include <exception>

int main(int argc, char **argv)
{
    if (argc != 3 || (std::strcmp(argv[1], "cells") != 0 && std::strcmp(argv[1], "scalar") != 0)) {
        std::fprintf(stderr, "usage: %s cells|scalar FILE\n", argv[0]);
        return 2;
    }
    try {
        const bool cells = std::strcmp(argv[1], "cells") == 0;
        const msidrec::Record r = msidrec::read_record_csv(argv[2], {}, false, cells);
        // the path taken, so a count is never read for the wrong one
        std::printf("%zu rows, %zu by the general parser\n", r.n_rows, r.general_lines);
    } catch (const std::exception &e) {
        std::fprintf(stderr, "msid_insn_csv: %s\n", e.what());
        return 1;
    }
    return 0;
}
