function Z = pagemtimes(X, varargin)
% Z = pagemtimes(X, Y) or pagemtimes(X, transpX, Y, transpY): the matrix product of every page
% (dimensions 3 and up) of X and Y, with MATLAB's options 'none', 'transpose', 'ctranspose' and its
% broadcasting of a single page. A stand-in for Octave, which has no pagemtimes (msid's own code).
  if numel(varargin) == 1
    tx = 'none'; Y = varargin{1}; ty = 'none';
  elseif numel(varargin) == 3
    tx = varargin{1}; Y = varargin{2}; ty = varargin{3};
  else
    error('pagemtimes: expected (X, Y) or (X, transpX, Y, transpY)');
  end
  X = page_op(X, tx);
  Y = page_op(Y, ty);
  if ndims(X) <= 2 && ndims(Y) <= 2
    Z = X * Y;
    return;
  end
  if size(X, 2) ~= size(Y, 1)
    error('pagemtimes: inner dimensions %d and %d differ', size(X, 2), size(Y, 1));
  end
  % sum over the inner index of (m x 1 x pages) .* (1 x n x pages): broadcasting pairs the pages
  % (or repeats a single one), a loop over the inner index only
  Z = zeros(size(X, 1), size(Y, 2));
  for l = 1:size(X, 2)
    Z = Z + X(:, l, :) .* Y(l, :, :);
  end
end

function A = page_op(A, t)
  switch lower(t)
    case 'none'
    case 'transpose'
      A = permute(A, [2, 1, 3:max(3, ndims(A))]);
    case 'ctranspose'
      A = conj(permute(A, [2, 1, 3:max(3, ndims(A))]));
    otherwise
      error('pagemtimes: unknown option ''%s''', t);
  end
end
