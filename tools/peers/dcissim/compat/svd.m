function varargout = svd(A, varargin)
% MATLAB's [U, S, V] = svd(A, 'vector') returns S as a vector of singular values (U, V full unless
% 'econ' or 0 is given too). Octave 7 takes the flag for 'econ' and returns the matrix S: the
% authors' idenACN then reads S(1:n) as the first n entries of its first column (s1 and zeros) and
% A-hat comes out with n - 1 poles at zero. This stand-in takes the 'vector' / 'matrix' flag off and
% shapes S as MATLAB does; everything else goes to the built-in svd unchanged (msid's own code).
  as_vector = nargout <= 1;   % a single output is the vector of singular values in both
  args = {};
  for k = 1:numel(varargin)
    a = varargin{k};
    if ischar(a) && strcmpi(a, 'vector')
      as_vector = true;
    elseif ischar(a) && strcmpi(a, 'matrix')
      as_vector = false;
    else
      args{end + 1} = a; %#ok<AGROW>
    end
  end
  if nargout <= 1
    s = builtin('svd', A, args{:});
    if ~as_vector
      s = diag(s);   % 'matrix' with one output: MATLAB gives the diagonal matrix
    end
    varargout{1} = s;
    return;
  end
  [U, S, V] = builtin('svd', A, args{:});
  if as_vector
    S = diag(S);
  end
  varargout = {U, S, V};
  varargout = varargout(1:max(nargout, 1));
end
