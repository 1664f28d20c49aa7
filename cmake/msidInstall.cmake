# `cmake --install build --prefix P` (docs/install.md): headers, static libraries, `msid` and `msid-devsim`,
# the Python package (P/share/msid/python, found by `msid plot`), P/lib/cmake/msid/msidConfig.cmake
# exporting msid::core, msid::daq, msid::fit and the host libraries (msid::hostutil, msid::records,
# msid::formats, msid::frfjob, msid::fitjob, msid::frfimport, msid::frfexport, msid::acquire, with msid::fftw and
# msid::est beneath them), and P/lib/pkgconfig/msid.pc
# (core + daq, C).
include(CMakePackageConfigHelpers)
set(MSID_CMAKE_DIR lib/cmake/msid)

set_target_properties(msid PROPERTIES EXPORT_NAME core)
install(TARGETS msid EXPORT msidTargets ARCHIVE DESTINATION lib)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/lib/include/ DESTINATION include FILES_MATCHING PATTERN "*.h")
if(TARGET msid_daq)
  set_target_properties(msid_daq PROPERTIES EXPORT_NAME daq)
  # msid::devdesc_file reads msid-device/1 descriptions (C API; toml++ header-only inside)
  set_target_properties(msid_devdesc_file PROPERTIES EXPORT_NAME devdesc_file)
  install(TARGETS msid_daq msid_devdesc_file EXPORT msidTargets ARCHIVE DESTINATION lib)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/daq/include/ DESTINATION include FILES_MATCHING PATTERN "*.h")
endif()
# the FRF stage's statistics (tools/frfstat), beneath the FRF job and the fits
if(TARGET msid_frfstat)
  set_target_properties(msid_frfstat PROPERTIES EXPORT_NAME frfstat)
  install(TARGETS msid_frfstat EXPORT msidTargets ARCHIVE DESTINATION lib)
  install(FILES ${PROJECT_SOURCE_DIR}/tools/frfstat/stats.hpp ${PROJECT_SOURCE_DIR}/tools/frfstat/bla.hpp
          DESTINATION include/msid_host)
endif()
if(TARGET msid_fit)
  set_target_properties(msid_fit PROPERTIES EXPORT_NAME fit)
  # msid::fit reads FRF files through msid_frffile (tools/frffile), exported beside it as msid::frffile
  set_target_properties(msid_frffile PROPERTIES EXPORT_NAME frffile)
  install(TARGETS msid_fit msid_frffile EXPORT msidTargets ARCHIVE DESTINATION lib)
  install(FILES ${PROJECT_SOURCE_DIR}/tools/frffile/frf_file.hpp ${PROJECT_SOURCE_DIR}/tools/frffile/frf_text.hpp
          DESTINATION include/msid_fit)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/fit/ DESTINATION include/msid_fit FILES_MATCHING PATTERN "*.hpp")
endif()
# The host libraries (tools/util, records, formats, frfjob; docs/architecture.md): the FRF job on
# records in memory or in files, without the command line. Their public headers go to include/msid_host;
# the libraries they link privately (FFTW's backend, the estimators) are exported too, a static
# library's consumer links them.
set(MSID_HAVE_HOST OFF)
if(TARGET msid_frfjob)
  set(MSID_HAVE_HOST ON)
  set(_host msid_hostutil msid_records msid_formats msid_frfjob msid_fftw)
  set_target_properties(msid_hostutil PROPERTIES EXPORT_NAME hostutil)
  set_target_properties(msid_records PROPERTIES EXPORT_NAME records)
  set_target_properties(msid_formats PROPERTIES EXPORT_NAME formats)
  set_target_properties(msid_frfjob PROPERTIES EXPORT_NAME frfjob)
  set_target_properties(msid_fftw PROPERTIES EXPORT_NAME fftw)
  if(TARGET msid_est)
    set_target_properties(msid_est PROPERTIES EXPORT_NAME est)
    list(APPEND _host msid_est)
    install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/est/ DESTINATION include/msid_est FILES_MATCHING PATTERN "*.hpp")
  endif()
  install(TARGETS ${_host} EXPORT msidTargets ARCHIVE DESTINATION lib)
  install(FILES ${PROJECT_SOURCE_DIR}/tools/util/msid_host_error.hpp ${PROJECT_SOURCE_DIR}/tools/util/msid_options.hpp
                ${PROJECT_SOURCE_DIR}/tools/util/msid_host_util.hpp
                ${PROJECT_SOURCE_DIR}/tools/util/msid_fftw_planner.hpp ${PROJECT_SOURCE_DIR}/tools/util/msid_cancel.hpp
                ${PROJECT_SOURCE_DIR}/tools/util/msid_partial_file.hpp
                ${PROJECT_SOURCE_DIR}/tools/records/msid_records.hpp ${PROJECT_SOURCE_DIR}/tools/records/msid_reference.hpp
                ${PROJECT_SOURCE_DIR}/tools/formats/msid_design_file.hpp ${PROJECT_SOURCE_DIR}/tools/formats/msid_json_file.hpp
                ${PROJECT_SOURCE_DIR}/tools/frfjob/msid_frf_job.hpp ${PROJECT_SOURCE_DIR}/tools/frfjob/msid_frf_est.hpp
                ${PROJECT_SOURCE_DIR}/tools/frfjob/msid_frf_result.hpp
          DESTINATION include/msid_host)
  # fitting and validation as one call (tools/fitjob, over msid::fit), FRFs of other tools
  # (tools/frfimport) and the FRF and model exporters (tools/frfexport)
  if(TARGET msid_fitjob AND TARGET msid_fit)
    set_target_properties(msid_fitjob PROPERTIES EXPORT_NAME fitjob)
    set_target_properties(msid_frfimport PROPERTIES EXPORT_NAME frfimport)
    set_target_properties(msid_frfexport PROPERTIES EXPORT_NAME frfexport)
    install(TARGETS msid_fitjob msid_frfimport msid_frfexport EXPORT msidTargets ARCHIVE DESTINATION lib)
    install(FILES ${PROJECT_SOURCE_DIR}/tools/fitjob/msid_fit_job.hpp ${PROJECT_SOURCE_DIR}/tools/frfimport/frf_import.hpp
                  ${PROJECT_SOURCE_DIR}/tools/frfexport/msid_frf_export.hpp
            DESTINATION include/msid_host)
  endif()
  # the acquisition of a device (tools/acquire, over msid::daq)
  if(TARGET msid_acquire)
    set_target_properties(msid_acquire PROPERTIES EXPORT_NAME acquire)
    set_target_properties(msid_canopen PROPERTIES EXPORT_NAME canopen)
    install(TARGETS msid_acquire msid_canopen EXPORT msidTargets ARCHIVE DESTINATION lib)
    install(FILES ${PROJECT_SOURCE_DIR}/tools/acquire/msid_acquire.hpp ${PROJECT_SOURCE_DIR}/tools/acquire/msid_device_uri.hpp
                  ${PROJECT_SOURCE_DIR}/tools/acquire/msid_ondevice.hpp ${PROJECT_SOURCE_DIR}/tools/acquire/msid_can_replay.hpp
                  ${PROJECT_SOURCE_DIR}/tools/acquire/msid_param_upload.hpp ${PROJECT_SOURCE_DIR}/tools/acquire/msid_can_acq.hpp
                  ${PROJECT_SOURCE_DIR}/tools/acquire/msid_canopen.hpp
            DESTINATION include/msid_host)
  endif()
endif()
foreach(t msid_cli msid_devsim)
  if(TARGET ${t})
    install(TARGETS ${t} RUNTIME DESTINATION bin)
  endif()
endforeach()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/python/msid DESTINATION share/msid/python
        PATTERN "__pycache__" EXCLUDE PATTERN "*.pyc" EXCLUDE)
install(FILES ${PROJECT_SOURCE_DIR}/tools/python/pyproject.toml ${PROJECT_SOURCE_DIR}/tools/python/README.md
        DESTINATION share/msid/python)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/schemas DESTINATION share/msid)

install(EXPORT msidTargets NAMESPACE msid:: DESTINATION ${MSID_CMAKE_DIR})
if(NOT DEFINED MSID_HAVE_MODBUS)
  set(MSID_HAVE_MODBUS OFF)
endif()
set(MSID_HAVE_FIT OFF)
if(TARGET msid_fit)
  set(MSID_HAVE_FIT ON)
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/msidConfig.cmake.in
  ${PROJECT_BINARY_DIR}/msidConfig.cmake INSTALL_DESTINATION ${MSID_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/msidConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${PROJECT_BINARY_DIR}/msidConfig.cmake ${PROJECT_BINARY_DIR}/msidConfigVersion.cmake
        DESTINATION ${MSID_CMAKE_DIR})

# pkg-config: the C libraries (core, and daq when built); libmodbus as a private requirement.
set(MSID_PC_LIBS "-lmsid")
set(MSID_PC_REQUIRES_PRIVATE "")
if(TARGET msid_daq)
  set(MSID_PC_LIBS "-lmsid_daq -lmsid")
  if(MSID_HAVE_MODBUS)
    set(MSID_PC_REQUIRES_PRIVATE "libmodbus")
  endif()
endif()
configure_file(${PROJECT_SOURCE_DIR}/cmake/msid.pc.in ${PROJECT_BINARY_DIR}/msid.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/msid.pc DESTINATION lib/pkgconfig)
