// libFuzzer: the file readers of the command line, through their own entry points: the first byte picks
// the reader, the rest is the file. msid-frf/1 (read_frf), msid-model/1 (read_model), msid-design/1
// (read_design_file), experiment CSV (read_record_csv) and the binary records: .npy (read_record_npy, the
// copying and the zero-copy path), .npz (read_record_npz: zip, stored and deflated members, zip64) and
// .mat (read_record_mat: v5 by msid's own reader, v4 and v7.3 through libmatio). Seeds: corpus/fuzz_files/ (npy-*,
// npz-*, mat-* from gen_file_seeds.py; regress-* crafted by hostile_files.py or found by fuzzing). A reader must
// return a value or throw its one error; any other exception, a crash, a sanitizer report or (run_fuzz.sh) a
// single allocation of 512 MiB or more is a finding.
#include "msid_records.hpp"
#include "msid_design_file.hpp"
#include "frf_data.hpp"
#include "model_io.hpp"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <string>
#include <unistd.h>

static std::string tmp_path()
{
    static std::string p;
    if (p.empty()) p = "/tmp/msid-fuzz-files." + std::to_string(getpid());
    return p;
}

// The CSV reader's cell path and general path (csv_io.cpp) must agree: the same rows bit for bit or
// the same error message; a difference is a finding (abort).
static void csv_both_paths(const std::string &path)
{
    std::string err[2];
    msidrec::Record rec[2];
    for (int k = 0; k < 2; ++k) {
        try {
            rec[k] = msidrec::read_record_csv(path, {}, true, k == 0);
        } catch (const msidutil::Error &e) {
            err[k] = e.what();
        }
    }
    if (err[0] != err[1] || rec[0].n_rows != rec[1].n_rows || rec[0].rows.size() != rec[1].rows.size() ||
        (!rec[0].rows.empty() &&
         std::memcmp(rec[0].rows.data(), rec[1].rows.data(), rec[0].rows.size() * sizeof(double)) != 0)) {
        std::fprintf(stderr, "CSV cell path and general path differ: '%s' / '%s'\n", err[0].c_str(), err[1].c_str());
        std::abort();
    }
    if (!err[0].empty()) throw msidutil::Error(err[0]);
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    const std::string path = tmp_path();
    FILE *f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
    try {
        static const msidrec::ColumnMap two = msidrec::parse_column_map("u1=1,y1=2");
        switch (data[0] % 8) {
        case 0: (void)msidfit::read_frf(path); break;
        case 1: (void)msidfit::read_model(path); break;
        case 2: (void)msidfmt::read_design_file(path); break;
        case 3: csv_both_paths(path); break;
        case 4: (void)msidrec::read_record_npy(path, {}, false); break;
        case 5: (void)msidrec::read_record_npy(path, two, true); break;   // the zero-copy view
        case 6: (void)msidrec::read_record_npz(path, {}); break;
        default: (void)msidrec::read_record_mat(path, {}); break;
        }
    } catch (const msidfit::FitError &) {
    } catch (const msidutil::Error &) {
    }
    return 0;
}
