function st = msid_dcissim_setup(T, lines, nu, ny, nbar, order, lags)
% The set-up structure that the authors' idenDCISSIMRunner reads, for a given set of DFT bins
% (`lines`, 0 <= bin < T/2) instead of their launcher's own choice (the full set, or lines picked
% from the input's spectrum by a heuristic that needs isoutlier). The fields follow the paper's
% eq. (7) and Alg. 1 with phase 0: per line the rotation S = [cos w, sin w; -sin w, cos w], its
% eigenvectors [1i, -1i; 1, 1] and eigenvalues exp(-+ 1i w), the regressors sin(w k) and cos(w k);
% the DC line (bin 0) is the constant 1/sqrt(2). msid's own code (tools/peers/dcissim/README.md).
  lines = unique(lines(:)');
  dc = ~isempty(lines) && lines(1) == 0;
  harm = lines(lines > 0);
  w = 2 * pi * harm / T;
  v = 2 * numel(harm) + dc;
  mat_s = zeros(v); eig_mat = zeros(v); eig_vec = zeros(v, 1);
  freq_list = zeros(v, 1); phi_list = zeros(v, 1);
  o = 0;
  if dc
    mat_s(1, 1) = 1; eig_mat(1, 1) = 1; eig_vec(1) = 1; phi_list(1) = pi / 4;
    o = 1;
  end
  for k = 1:numel(w)
    i = o + 2 * k - 1;
    mat_s(i:i + 1, i:i + 1) = [cos(w(k)), sin(w(k)); -sin(w(k)), cos(w(k))];
    eig_mat(i:i + 1, i:i + 1) = [1i, -1i; 1, 1];
    eig_vec(i:i + 1) = [exp(-1i * w(k)); exp(1i * w(k))];
    freq_list(i:i + 1) = w(k);
    phi_list(i + 1) = pi / 2;
  end
  mat_v = sin(freq_list * (0:T - 1) + phi_list);
  regressor = struct('v0', sin(phi_list), 'freq_list', freq_list, 'phi_list', phi_list);
  st = struct('mat_s', mat_s, 'mat_v', mat_v, 'eig_mat', eig_mat, 'eig_vec', eig_vec, 'regressor', regressor, ...
              'y_size', ny, 'u_size', nu, 'x_size_upbound', nbar, 'T', T, 'algo_type', 'offline', ...
              'xsize_est_type', 'fixed', 'aorder_est_type', 'fixed', 'als_est_type', 'none', 'plant_d_type', 'null', ...
              'prior', struct('xsize', order, 'aorder', lags), 'hop_length', 1);
end
