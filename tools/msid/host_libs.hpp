// The host libraries as the command line sees them: their public headers, and their names in
// msidcli, so that each command reads as options -> one library call -> output.
#pragma once
#include "cli_util.hpp"
#include "frf_bla.hpp"
#include "frf_doc.hpp"
#include "msid_design_file.hpp"
#include "msid_fftw_planner.hpp"
#include "msid_frf_job.hpp"
#include "msid_json_file.hpp"
#include "msid_records.hpp"
#include "msid_reference.hpp"
#include "nl_verdict.hpp"
#include "periodicity.hpp"

namespace msidcli {

// records (tools/records)
using msidrec::Record;
using msidrec::Samples;
using msidrec::ColumnMap;
using msidrec::parse_column_map;
using msidrec::read_experiment;
using msidrec::read_experiments;
using msidrec::read_record_csv;
using msidrec::read_record_npy;
using msidrec::read_record_npz;
using msidrec::read_record_mat;
using msidrec::check_finite;
using msidrec::format_csv;
using msidrec::is_time_name;
using msidrec::FileBytes;
using msidrec::parse_reference;
using msidrec::rows_with_reference;
// formats (tools/formats)
using msidfmt::Json;
using msidfmt::DesignParams;
using msidfmt::Design;
using msidfmt::build_design;
using msidfmt::design_to_json;
using msidfmt::read_design_file;
using msidfmt::read_json_file;
using msidfmt::write_json_file;
using msidfmt::jget;
using msidfmt::juint;
using msidfmt::juint32;
using msidfmt::jnum;
// the FFTW planner lock (tools/util)
using msidutil::fftw_warmup_start;
using msidutil::fftw_planner_ready;
// the FRF job (tools/frfjob)
using msidjob::FrfRequest;
using msidjob::FrfOutcome;
using msidjob::FrfJob;
using msidjob::ExpSource;
using msidjob::request_from_design;
using msidjob::request_from_core_design;
using msidjob::check_records;
using msidjob::run_frf;
using msidjob::run_frf_direct;
using msidjob::run_frf_realisations;
using msidjob::frf_header;
using msidjob::line_position;
using msidjob::cplx_json;
using msidjob::est_line_json;
using msidjob::detection_distortion;
using msidjob::find_period;
using msidjob::find_lines;
using msidjob::format_bins;
using msidjob::check_periodic_inputs;
using msidjob::check_periodic_lines;
using msidjob::nonperiodic_fraction;
using msidjob::periodic_evidence;
using msidjob::NONPERIODIC_FRACTION;

// --skip-periods, --detect-lines, --transient, --alpha, --dft (shared by the estimating commands).
void parse_estimate_options(const Args &a, FrfRequest &rq);

}  // namespace msidcli
