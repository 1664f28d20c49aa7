// msid_records' CAN side: a DBC file read whole (daq's msid_dbc), the frames of a candump .log with
// their line numbers, and a log decoded with a DBC as an experiment record (msid frf --dbc). Errors
// as the other readers: msidrec::Error naming the file and line, FileError for a file that cannot be
// read, ColumnSpecError for a column map that does not name DBC signals.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "msid_records.hpp"

extern "C" {
#include "msid_daq/msid_candump.h"
#include "msid_daq/msid_dbc.h"
}

namespace msidrec {

// A DBC file in memory this object owns. Throws FileError (cannot read) or Error
// "'FILE' line N: what is wrong" (a file msid_dbc_init refuses).
class DbcFile {
public:
    explicit DbcFile(const std::string &path);
    DbcFile(const DbcFile &) = delete;
    DbcFile &operator=(const DbcFile &) = delete;
    const msid_dbc &db() const { return d_; }
    const std::string &path() const { return path_; }
    // The signal a --columns entry names as MESSAGE.SIGNAL; `target` (u1, y2) names the entry in the
    // ColumnSpecError thrown for a spec that is not MESSAGE.SIGNAL or names no message or signal of the file.
    const msid_dbc_signal &signal(const std::string &spec, const std::string &target) const;

private:
    std::string path_;
    std::vector<uint64_t> mem_;   // the tables and names (8-byte aligned)
    msid_dbc d_{};
};

// Every frame of a candump .log in file order with its line number (1 = the first); `take` returns
// false to stop early. Blank lines are skipped. Throws FileError, or Error
// "'FILE' line N is not a candump log line: '...'" (nothing after that line is read).
void for_each_candump_frame(const std::string &path,
                            const std::function<bool(const msid_can_frame &, uint64_t line)> &take);

// Does this text line read as a candump log line? (A .log given to a reader that expects CSV is named so.)
bool is_candump_line(const std::string &line);

// A file named *.log whose first non-blank line is a candump log line, given where a CSV record is read
// (no --dbc): throws ColumnSpecError saying so and naming --dbc and --columns MESSAGE.SIGNAL. Any other
// file (or one that cannot be opened: its reader names it) passes.
void refuse_candump_without_dbc(const std::string &path);

// What read_record_candump met besides the rows (all counted, none averaged in).
struct CandumpCounts {
    uint64_t frames = 0;          // frames in the log
    uint64_t row_frames = 0;      // frames of the row message (one row each)
    uint64_t lost = 0;            // row-message samples missing from gaps in its timestamps (NaN rows)
    uint64_t gaps = 0;            // those gaps
    uint64_t short_frames = 0;    // row-message frames too short for one of its columns (NaN rows)
    uint64_t before_values = 0;   // rows before every column had a value (NaN rows)
    uint64_t nonfinite = 0;       // rows whose float signal carried NaN or infinity
    uint64_t unknown_ids = 0;     // frames whose identifier the DBC does not define
    uint64_t error_frames = 0;    // error frames
    double interval_s = 0;        // the row message's sample interval (median of its frame intervals)
};

// A candump log decoded with a DBC as an experiment record (msid frf --dbc): `cols` maps u1.., y1.. to
// MESSAGE.SIGNAL. One row per frame of the first column's message (the rows' clock); a column of
// another message holds its latest value at or before that frame. A frame lost from the row message
// (a gap in its timestamps over 1.5 times its median interval) becomes NaN rows for the missing
// samples, so the FRF job rejects and counts every period they touch, never interpolates; so do rows
// before every column has a value and frames too short for a column. Record::columns are the signal
// names with the DBC's units ("speed [km/h]"); `counts` gets what was counted, `notes` one
// line per kind of thing counted. Throws Error naming the file, line and column.
Record read_record_candump(const std::string &path, const DbcFile &dbc, const ColumnMap &cols,
                           std::vector<std::string> &notes, CandumpCounts *counts = nullptr);

}  // namespace msidrec
