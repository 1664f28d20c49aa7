// libFuzzer: the readers of FRFs measured by other tools (tools/frfimport, `msid import`), through the
// entry point every command takes (load_document: the reader, then the msid-frf/1 checks of parse_frf):
// the first byte picks the format (Touchstone 1.x or 2.x as .s1p/.s2p/.s3p, UFF 58, CSV, idfrd .mat), the rest is
// the file. Seeds: corpus/fuzz_frf_import/. A reader must return a document or throw its one error
// (msidutil::Error, or msidfrf::Error from parse_frf); anything else is a finding.
#include "frf_import.hpp"

#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    static const char *const ext[] = {".s1p", ".s2p", ".s3p", ".uff", ".csv", ".mat"};
    const std::string path = "/tmp/msid-fuzz-import." + std::to_string(getpid()) + ext[data[0] % 6];
    FILE *f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
    try {
        (void)msidfrf::parse_frf(msidfrfimport::load_document(path), path);
    } catch (const msidutil::Error &) {
    } catch (const msidfrf::Error &) {
    }
    std::remove(path.c_str());
    return 0;
}
