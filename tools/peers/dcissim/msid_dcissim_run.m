function msid_dcissim_run(data, n_rows, nu, ny, T, lines, order, nbar, lags, out)
% One whole run of the authors' discrete-cISSIM code (github wyqy/dcissim, found through
% $MSID_DCISSIM_DIR) on a record: read the samples (raw little-endian float64, n_rows x (nu + ny)
% row-major, [u, y]; or a CSV file with a header line, by its .csv ending), set up for `lines`, estimate A, B, C (D = 0: their 'null' direct term) with
% order `order` and `nbar` block rows by their idenDCISSIMRunner (first period skipped, as theirs),
% then the noise covariance by their idenISIM ('fft') and idenCovariance ('simple', `lags` lags; 0:
% skipped). Writes `out`: the matrices, the covariances and the seconds of each step (tic/toc).
% Run by `msid bench fit --cissim-process` and tests/integration/test_dcissim_peer.py.
  t_all = tic;
  here = fileparts(mfilename('fullpath'));
  ref = getenv('MSID_DCISSIM_DIR');
  if isempty(ref) || ~exist(fullfile(ref, 'identificator', 'idenDCISSIMRunner.m'), 'file')
    error('msid_dcissim_run: MSID_DCISSIM_DIR must hold the authors'' code (identificator/idenDCISSIMRunner.m)');
  end
  % The stand-ins (compat/) must reach the authors' functions as private functions: Octave lets no
  % function on the path shadow a built-in one (svd, qr), but a private/ folder beside the calling
  % files comes first. So the authors' files are linked, unchanged, into a folder of this run whose
  % private/ is compat/.
  work = tempname();
  mkdir(work);
  files = dir(fullfile(ref, 'identificator', '*.m'));
  for k = 1:numel(files)
    symlink(fullfile(ref, 'identificator', files(k).name), fullfile(work, files(k).name));
  end
  symlink(fullfile(here, 'compat'), fullfile(work, 'private'));
  addpath(work);
  cleanup = onCleanup(@() remove_links(work));
  t = tic;
  if numel(data) > 4 && strcmpi(data(end - 3:end), '.csv')
    X = dlmread(data, ',', 1, 0).';   % a header line, then n_rows rows of u.., y..
  else
    fid = fopen(data, 'r', 'ieee-le');
    if fid < 0
      error('msid_dcissim_run: cannot open %s', data);
    end
    X = fread(fid, [nu + ny, n_rows], 'double');
    fclose(fid);
  end
  if ~isequal(size(X), [nu + ny, n_rows])
    error('msid_dcissim_run: %s holds %d x %d values, not %d x %d', data, size(X, 2), size(X, 1), n_rows, nu + ny);
  end
  uk = X(1:nu, :); yk = X(nu + 1:end, :);
  t_read = toc(t);
  t = tic;
  st = msid_dcissim_setup(T, lines, nu, ny, nbar, order, lags);
  t_setup = toc(t);
  t = tic;
  clear idenISIM idenDCISSIMRunner
  res = idenDCISSIMRunner(st, yk, uk);
  t_est = toc(t);
  t = tic;
  cov = [];
  if lags > 0
    % the samples the runner used: the first period skipped, whole periods only
    K = fix((size(yk, 2) - T) / T);
    ykt = yk(:, T + 1:T + K * T); ukt = uk(:, T + 1:T + K * T);
    [~, ~, yw, uw] = idenISIM(ykt, ukt, st.mat_v, T, 'fft');
    cov = idenCovariance(ykt, ukt, T, struct('Y', yw, 'U', uw, 'A', res.A, 'C', res.C), 'simple', lags, 'fixed');
  end
  t_cov = toc(t);
  fid = fopen(out, 'w');
  put(fid, 'A', res.A); put(fid, 'B', res.B); put(fid, 'C', res.C); put(fid, 'D', res.D);
  if ~isempty(cov)
    put(fid, 'Sigma_ww', cov.cov_xx); put(fid, 'Sigma_vv', cov.cov_yy); put(fid, 'Sigma_tt', cov.cov_uu);
  end
  fprintf(fid, 'seconds read %.6f setup %.6f estimate %.6f covariance %.6f inside %.6f\n', ...
          t_read, t_setup, t_est, t_cov, toc(t_all));
  fclose(fid);
end

function remove_links(work)
  rmpath(work);
  files = dir(work);
  for k = 1:numel(files)
    if ~any(strcmp(files(k).name, {'.', '..'}))
      unlink(fullfile(work, files(k).name));
    end
  end
  rmdir(work);
end

function put(fid, name, M)
  fprintf(fid, '%s %d %d', name, size(M, 1), size(M, 2));
  fprintf(fid, ' %.17g', real(M(:)));
  fprintf(fid, '\n');
end
